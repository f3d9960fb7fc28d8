#version 450
// AdaFace margin logits (Kim et al. 2022, kernels/adaface.hpp) over cos [B, C]:
//   c = clamp(cos, −1 + eps, 1 − eps)
//   j ≠ label: s·c
//   j = label: θ′ = clip(acos(c) − m·ẑ, eps, π − eps); s·(cos θ′ − m − m·ẑ)
// BACKWARD: d cos = dy · s (· sin θ′ / sqrt(1 − c²) on the label column),
// zero where a clamp is active. A label outside [0, C) gives a NaN row.
// 4 elements per invocation, inputs through uniform texel buffers.
#include "common.glsl"
layout(local_size_x = 256) in;
layout(constant_id = 0) const bool BACKWARD = false;
layout(binding = 0) uniform samplerBuffer cosine;
layout(binding = 1) uniform isamplerBuffer label;
layout(binding = 2) uniform samplerBuffer scaler;
layout(binding = 3) uniform samplerBuffer dy;  // backward only
layout(std430, binding = 4) writeonly buffer Out { float o[]; };
layout(push_constant) uniform Push {
  uint n;        // B·C
  uint classes;  // C
  uvec2 row_magic;  // fast_div by C
  float s;
  float m;
  float eps;
} pc;

// sin and cos for |x| ≤ 1.1 (|m ẑ| ≤ 1, eps ≤ 0.1) by Taylor series to x^13
// and x^12 (truncation < 1e-11). Vulkan promises only 2^-11 absolute error for
// the built-in sin/cos and less for acos; lavapipe's acos/cos were off by
// 1e-4 here, 0.007 in a logit scaled by 64.
float sin_small(float x) {
  const float x2 = x * x;
  return x * (1.0 + x2 * (-1.0 / 6.0 + x2 * (1.0 / 120.0 + x2 * (-1.0 / 5040.0 +
         x2 * (1.0 / 362880.0 + x2 * (-1.0 / 39916800.0 + x2 * (1.0 / 6227020800.0)))))));
}
float cos_small(float x) {
  const float x2 = x * x;
  return 1.0 + x2 * (-0.5 + x2 * (1.0 / 24.0 + x2 * (-1.0 / 720.0 + x2 * (1.0 / 40320.0 +
         x2 * (-1.0 / 3628800.0 + x2 * (1.0 / 479001600.0))))));
}

float element(uint i) {
  const uint row = fast_div(i, pc.row_magic);
  const int col = int(i - row * pc.classes);
  const int target = texelFetch(label, int(row)).r;
  if (target < 0 || uint(target) >= pc.classes) return uintBitsToFloat(0x7fc00000u);
  const float x = texelFetch(cosine, int(i)).r;
  if (isnan(x)) return x;
  const float lo = -1.0 + pc.eps, hi = 1.0 - pc.eps;
  const bool inside = x >= lo && x <= hi;
  const float c = clamp(x, lo, hi);
  const float g = BACKWARD ? texelFetch(dy, int(i)).r * pc.s : 0.0;
  if (col != target) {
    if (BACKWARD) return inside ? g : 0.0;
    return pc.s * c;
  }
  // θ′ = θ − δ with θ = acos(c), δ = m ẑ, without acos:
  // cos(θ − δ) = c cos δ + sin θ sin δ, sin θ = sqrt((1 − c)(1 + c)) ≥ sqrt(eps).
  // The clip of θ′ to [eps, π − eps] becomes a test on c (cos falls on [0, π]):
  // θ′ < eps ⇔ c > cos(eps + δ); θ′ > π − eps ⇔ c < −cos(eps − δ).
  const float z = texelFetch(scaler, int(row)).r;
  if (isnan(z)) return z;  // a NaN norm
  const float delta = pc.m * z;
  const float sin_theta = sqrt((1.0 - c) * (1.0 + c));
  const float sd = sin_small(delta), cd = cos_small(delta);
  float cos_m;
  bool open = false;
  if (pc.eps + delta > 0.0 && c > cos_small(pc.eps + delta)) {
    cos_m = cos_small(pc.eps);
  } else if (delta < pc.eps && c < -cos_small(pc.eps - delta)) {
    cos_m = -cos_small(pc.eps);
  } else {
    cos_m = c * cd + sin_theta * sd;
    open = true;
  }
  if (BACKWARD) {
    // d/dc cos(acos(c) − δ) = sin θ′ / sin θ = cos δ − c sin δ / sin θ.
    return (inside && open) ? g * (cd - c * sd / sin_theta) : 0.0;
  }
  return pc.s * (cos_m - pc.m - pc.m * z);
}

void main() {
  const uint base = linear_group() * 1024u + gl_LocalInvocationID.x;
  [[unroll]] for (uint k = 0u; k < 4u; ++k) {
    const uint i = base + k * 256u;
    if (i < pc.n) o[i] = element(i);
  }
}
