#version 450
// PSF-basis convolution sum, direct path (one output pixel per invocation):
//   A[n,c,p] = Σ_k Σ_q ψ[k,q] · β[n,k,p−q] · x[n,c,p−q]
//   B[n,p]   = Σ_k Σ_q ψ[k,q] · β[n,k,p−q]
// with zero padding ("same" size), q over the S×S kernel centred at S/2 (true
// convolution). Output y = A (plain) or A / B (normalized), and B itself.
// x, β and ψ are read through uniform texel buffers (vector gathers on
// lavapipe); the tap loop loads x once per tap and reuses it for all K.
#include "common.glsl"
layout(local_size_x = 16, local_size_y = 8) in;
layout(constant_id = 0) const int S = 3;         // kernel size (odd)
layout(constant_id = 1) const int C = 1;         // image channels, 1..4
layout(constant_id = 2) const int NORMALIZE = 0; // 1: y = A / B
layout(binding = 0) uniform samplerBuffer x;     // [N, C, H, W]
layout(binding = 1) uniform samplerBuffer beta;  // [N, K, H, W]
layout(binding = 2) uniform samplerBuffer psi;   // [K, S, S]
layout(std430, binding = 3) writeonly buffer Y { float y[]; };       // [N, C, H, W]
layout(std430, binding = 4) writeonly buffer Norm { float norm[]; }; // [N, 1, H, W]
layout(push_constant) uniform Push { int N, K, H, W; } pc;

void main() {
  const int px = int(gl_GlobalInvocationID.x), py = int(gl_GlobalInvocationID.y);
  const int n = int(gl_GlobalInvocationID.z);
  if (px >= pc.W || py >= pc.H) return;
  const int plane = pc.H * pc.W;
  const int r = S / 2;
  vec4 acc = vec4(0.0);
  float b_acc = 0.0;
  for (int dy = -r; dy <= r; ++dy) {
    const int sy = py - dy;
    if (sy < 0 || sy >= pc.H) continue;
    for (int dx = -r; dx <= r; ++dx) {
      const int sx = px - dx;
      if (sx < 0 || sx >= pc.W) continue;
      const int s = sy * pc.W + sx;
      vec4 xv = vec4(0.0);
      [[unroll]] for (int c = 0; c < C; ++c) xv[c] = texelFetch(x, (n * C + c) * plane + s).r;
      const int tap = (dy + r) * S + (dx + r);
      float w = 0.0;
      for (int k = 0; k < pc.K; ++k) {
        w += texelFetch(psi, k * S * S + tap).r * texelFetch(beta, (n * pc.K + k) * plane + s).r;
      }
      acc += w * xv;
      b_acc += w;
    }
  }
  const int p = py * pc.W + px;
  const vec4 out_v = NORMALIZE == 1 ? acc / b_acc : acc;
  [[unroll]] for (int c = 0; c < C; ++c) y[(n * C + c) * plane + p] = out_v[c];
  norm[n * plane + p] = b_acc;
}
