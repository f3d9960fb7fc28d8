#version 450
// FFT path, step 3: out[n, c'] (+)= Σ_kk Ψ̂[k0 + kk] · U[n, kk, c'] bin by bin
// (complex products of half spectra, kernels/fft.hpp layout).
#include "common.glsl"
layout(local_size_x = 64) in;
layout(binding = 0) uniform samplerBuffer psi_hat;  // RG32F [K, bins]
layout(binding = 1) uniform samplerBuffer u_hat;    // RG32F [N, Kc, C + 1, bins]
layout(std430, binding = 2) buffer Out { vec2 o[]; };  // [N, C + 1, bins]
layout(push_constant) uniform Push { int bins, Kc, planes, k0, accumulate; } pc;  // planes = C + 1

void main() {
  const int b = int(gl_GlobalInvocationID.x);
  const int z = int(gl_GlobalInvocationID.y);  // n · planes + c'
  if (b >= pc.bins) return;
  const int n = z / pc.planes, c = z - n * pc.planes;
  vec2 acc = vec2(0.0);
  for (int kk = 0; kk < pc.Kc; ++kk) {
    const vec2 p = texelFetch(psi_hat, (pc.k0 + kk) * pc.bins + b).rg;
    const vec2 v = texelFetch(u_hat, ((n * pc.Kc + kk) * pc.planes + c) * pc.bins + b).rg;
    acc += vec2(p.x * v.x - p.y * v.y, p.x * v.y + p.y * v.x);
  }
  const int at = z * pc.bins + b;
  o[at] = pc.accumulate != 0 ? o[at] + acc : acc;
}
