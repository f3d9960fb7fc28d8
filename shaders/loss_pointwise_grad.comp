#version 450
// d pred of the pointwise losses of loss_pointwise.comp given the upstream
// scalar gradient g[0]: d = p - t, d pred = g/n · ρ'(d) with ρ' = sign(d)
// (L1, 0 at d = 0), 2d (MSE), d / sqrt(d² + eps²) (Charbonnier).
#include "common.glsl"
layout(local_size_x = 256) in;
layout(constant_id = 0) const uint OP = 0u;
layout(binding = 0) uniform samplerBuffer pred;
layout(binding = 1) uniform samplerBuffer target;
layout(binding = 2) uniform samplerBuffer g;
layout(std430, binding = 3) writeonly buffer Dp { float dp[]; };
layout(push_constant) uniform Push {
  uint n;
  float eps;
  float inv_n;
} pc;

float drho(float d) {
  if (OP == 0u) return sign(d);
  if (OP == 1u) return 2.0 * d;
  return d / sqrt(fma(d, d, pc.eps * pc.eps));
}

void main() {
  const float scale = texelFetch(g, 0).r * pc.inv_n;
  const uint base = linear_group() * 1024u + gl_LocalInvocationID.x;
  [[unroll]] for (uint u = 0u; u < 4u; ++u) {
    const uint i = base + u * 256u;
    if (i < pc.n) dp[i] = scale * drho(texelFetch(pred, int(i)).r - texelFetch(target, int(i)).r);
  }
}
