#version 450
// FFT path, step 5: crop the H × W image out of the Hp × Wp inverse
// transforms; y = A (plain) or A / B (normalized), norm = B.
#include "common.glsl"
layout(local_size_x = 16, local_size_y = 8) in;
layout(constant_id = 0) const int C = 1;
layout(constant_id = 1) const int NORMALIZE = 0;
layout(binding = 0) uniform samplerBuffer r;  // [N, C + 1, Hp, Wp]
layout(std430, binding = 1) writeonly buffer Y { float y[]; };        // [N, C, H, W]
layout(std430, binding = 2) writeonly buffer Norm { float norm[]; };  // [N, 1, H, W]
layout(push_constant) uniform Push { int N, H, W, Hp, Wp; } pc;

void main() {
  const int px = int(gl_GlobalInvocationID.x), py = int(gl_GlobalInvocationID.y);
  const int n = int(gl_GlobalInvocationID.z);
  if (px >= pc.W || py >= pc.H) return;
  const int padded = pc.Hp * pc.Wp, plane = pc.H * pc.W;
  const int src = n * (C + 1) * padded + py * pc.Wp + px;
  const float b = texelFetch(r, src + C * padded).r;
  const int p = py * pc.W + px;
  [[unroll]] for (int c = 0; c < C; ++c) {
    const float a = texelFetch(r, src + c * padded).r;
    y[(n * C + c) * plane + p] = NORMALIZE == 1 ? a / b : a;
  }
  norm[n * plane + p] = b;
}
