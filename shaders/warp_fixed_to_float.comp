#version 450
// d_img[i] = (64-bit two's complement fixed point (lo, hi) at acc[2i]) · 2^-s,
// the last pass of the deterministic d_img scatter (warp_sample_backward.comp).
// A non-finite max |d_out| makes every element NaN.
#include "warp_sampling.glsl"
layout(local_size_x = 256) in;
layout(std430, binding = 0) readonly buffer MaxAbs { uint max_abs_bits[]; };
layout(std430, binding = 1) readonly buffer Acc { uint acc[]; };
layout(std430, binding = 2) writeonly buffer Out { float d_img[]; };

void main() {
  const uint total = pc.n_batch * pc.channels * pc.in_h * pc.in_w;
  const uint base = linear_group() * 1024u + gl_LocalInvocationID.x;
  const uint m_bits = max_abs_bits[0];
  const bool finite = m_bits < 0x7f800000u;
  const int s = fixed_scale_exp(m_bits);
  [[unroll]] for (uint k = 0u; k < 4u; ++k) {
    const uint i = base + k * 256u;
    if (i >= total) break;
    uint lo = acc[2u * i], hi = acc[2u * i + 1u];
    const bool negative = (hi & 0x80000000u) != 0u;
    if (negative) {
      lo = ~lo + 1u;
      hi = ~hi + (lo == 0u ? 1u : 0u);
    }
    const float magnitude = float(hi) * 4294967296.0 + float(lo);
    const float v = scale_pow2(magnitude, -s);
    d_img[i] = finite ? (negative ? -v : v) : kNaN;
  }
}
