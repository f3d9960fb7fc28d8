#version 450
// NAFNet's SimpleGate: the channels' first half times the second half,
//   y[n, c, s] = x[n, c, s] · x[n, c + C, s],   x: [N, 2C, S], y: [N, C, S];
// BACKWARD = 1 writes dx from dy instead:
//   dx[n, c, s] = dy[n, c, s] · x[n, c + C, s],  dx[n, c + C, s] = dy[n, c, s] · x[n, c, s].
// Grid: x = 256-element chunks of one sample's C·S half (folded into x, y by
// groups_1d when large), z = n, so no division by a runtime size is needed.
#include "common.glsl"
layout(local_size_x = 256) in;
layout(constant_id = 0) const uint BACKWARD = 0u;
layout(binding = 0) uniform samplerBuffer x;
layout(binding = 1) uniform samplerBuffer dy;  // backward only (forward binds x again)
layout(std430, binding = 2) writeonly buffer Out { float o[]; };
layout(push_constant) uniform Push { uint half_size; } pc;  // C·S

void main() {
  const uint i = linear_group() * 256u + gl_LocalInvocationID.x;
  if (i >= pc.half_size) return;
  const uint n = gl_WorkGroupID.z;
  const uint a = n * 2u * pc.half_size + i, b = a + pc.half_size;
  const float xa = texelFetch(x, int(a)).r, xb = texelFetch(x, int(b)).r;
  if (BACKWARD == 0u) {
    o[n * pc.half_size + i] = xa * xb;
  } else {
    const float g = texelFetch(dy, int(n * pc.half_size + i)).r;
    o[a] = g * xb;
    o[b] = g * xa;
  }
}
