#version 450
// FFT path of the PSF-basis convolution (kernels/psf_conv.hpp), step 1:
// u[n, kk, c', y, x] = β[n, k0 + kk, y, x] · (c' < C ? x[n, c', y, x] : 1) on the
// zero-padded Hp × Wp grid (0 outside the H × W image); c' = C is the
// normalization's plane Σ_k ψ_k ⊛ β_k.
#include "common.glsl"
layout(local_size_x = 16, local_size_y = 8) in;
layout(constant_id = 0) const int C = 1;
layout(binding = 0) uniform samplerBuffer x;     // [N, C, H, W]
layout(binding = 1) uniform samplerBuffer beta;  // [N, K, H, W]
layout(std430, binding = 2) writeonly buffer U { float u[]; };  // [N, Kc, C + 1, Hp, Wp]
layout(push_constant) uniform Push { int N, K, H, W, Hp, Wp, k0, Kc; } pc;

void main() {
  const int px = int(gl_GlobalInvocationID.x), py = int(gl_GlobalInvocationID.y);
  const int z = int(gl_GlobalInvocationID.z);  // n · Kc + kk
  if (px >= pc.Wp || py >= pc.Hp) return;
  const int n = z / pc.Kc, kk = z - n * pc.Kc;
  const int padded = pc.Hp * pc.Wp;
  const int base = z * (C + 1) * padded + py * pc.Wp + px;
  if (px >= pc.W || py >= pc.H) {
    [[unroll]] for (int c = 0; c <= C; ++c) u[base + c * padded] = 0.0;
    return;
  }
  const int plane = pc.H * pc.W, s = py * pc.W + px;
  const float b = texelFetch(beta, (n * pc.K + pc.k0 + kk) * plane + s).r;
  [[unroll]] for (int c = 0; c < C; ++c) u[base + c * padded] = b * texelFetch(x, (n * C + c) * plane + s).r;
  u[base + C * padded] = b;
}
