#version 450
// Backward of psf_conv (direct path), gather form (deterministic, no atomics).
// With the upstream gradient g = dL/dy, for the plain form gA = g, gB = 0; for
// the normalized form y = A/B: gA_c = g_c / B, gB = −Σ_c g_c y_c / B. Then
//   t[k,c](s) = Σ_q ψ[k,q] gA_c(s+q)      (correlation: adjoint of ⊛)
//   u[k](s)   = Σ_q ψ[k,q] gB(s+q)
//   dβ[k](s)  = Σ_c x_c(s) t[k,c](s) + u[k](s)
//   dx_c(s)   = Σ_k β[k](s) t[k,c](s)
#include "common.glsl"
layout(local_size_x = 16, local_size_y = 8) in;
layout(constant_id = 0) const int S = 3;
layout(constant_id = 1) const int C = 1;
layout(constant_id = 2) const int NORMALIZE = 0;
layout(binding = 0) uniform samplerBuffer x;     // [N, C, H, W]
layout(binding = 1) uniform samplerBuffer beta;  // [N, K, H, W]
layout(binding = 2) uniform samplerBuffer psi;   // [K, S, S]
layout(binding = 3) uniform samplerBuffer g;     // [N, C, H, W] = dL/dy
layout(binding = 4) uniform samplerBuffer y;     // [N, C, H, W] (normalized form)
layout(binding = 5) uniform samplerBuffer norm;  // [N, 1, H, W] (normalized form)
layout(std430, binding = 6) writeonly buffer DX { float dx[]; };        // [N, C, H, W]
layout(std430, binding = 7) writeonly buffer DBeta { float dbeta[]; };  // [N, K, H, W]
layout(push_constant) uniform Push { int N, K, H, W; } pc;

// gA (xyzw = channels) and gB at pixel t of image n.
void upstream(int n, int t, int plane, out vec4 ga, out float gb) {
  ga = vec4(0.0);
  [[unroll]] for (int c = 0; c < C; ++c) ga[c] = texelFetch(g, (n * C + c) * plane + t).r;
  gb = 0.0;
  if (NORMALIZE == 1) {
    const float b = texelFetch(norm, n * plane + t).r;
    vec4 yv = vec4(0.0);
    [[unroll]] for (int c = 0; c < C; ++c) yv[c] = texelFetch(y, (n * C + c) * plane + t).r;
    gb = -dot(ga, yv) / b;
    ga /= b;
  }
}

void main() {
  const int px = int(gl_GlobalInvocationID.x), py = int(gl_GlobalInvocationID.y);
  const int n = int(gl_GlobalInvocationID.z);
  if (px >= pc.W || py >= pc.H) return;
  const int plane = pc.H * pc.W;
  const int r = S / 2;
  const int s = py * pc.W + px;
  vec4 xv = vec4(0.0);
  [[unroll]] for (int c = 0; c < C; ++c) xv[c] = texelFetch(x, (n * C + c) * plane + s).r;
  vec4 dx_acc = vec4(0.0);
  for (int k = 0; k < pc.K; ++k) {
    vec4 t = vec4(0.0);
    float u = 0.0;
    for (int dy = -r; dy <= r; ++dy) {
      const int ty = py + dy;
      if (ty < 0 || ty >= pc.H) continue;
      for (int dxo = -r; dxo <= r; ++dxo) {
        const int tx = px + dxo;
        if (tx < 0 || tx >= pc.W) continue;
        const float w = texelFetch(psi, k * S * S + (dy + r) * S + (dxo + r)).r;
        vec4 ga;
        float gb;
        upstream(n, ty * pc.W + tx, plane, ga, gb);
        t += w * ga;
        u += w * gb;
      }
    }
    const float b = texelFetch(beta, (n * pc.K + k) * plane + s).r;
    dbeta[(n * pc.K + k) * plane + s] = dot(xv, t) + u;
    dx_acc += b * t;
  }
  [[unroll]] for (int c = 0; c < C; ++c) dx[(n * C + c) * plane + s] = dx_acc[c];
}
