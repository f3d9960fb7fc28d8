#version 450
// Bilinear resampling backward, for warp and grid_sample (warp_sampling.glsl).
// One invocation per output pixel, all channels.
//
// d_coords (d_flow / d_grid) is a gather: each output pixel owns its entry.
//
// d_img is a scatter: many output pixels can hit one input pixel, anywhere
// (the displacement is unbounded). Float atomics are not portable and their
// summation order is not deterministic, so each contribution w·g is converted
// to a 64-bit fixed-point integer with a power-of-two scale 2^s and added with
// two 32-bit integer atomicAdds (low word, then the high word plus the carry
// seen from the low word's old value). Integer addition is associative, so
// the sums are exact and the same bits come out on every run and device.
// s comes from max |d_out| (warp_absmax.comp) and the number of output pixels
// so that no partial sum can overflow: the resolution is 2^-61 · max|d_out| ·
// Hout·Wout, far below fp32 rounding of the results. warp_fixed_to_float.comp
// converts the sums back to floats.
#include "warp_sampling.glsl"
layout(constant_id = 1) const bool kWantImage = true;
layout(constant_id = 2) const bool kWantCoords = true;
layout(local_size_x = 128) in;
layout(binding = 0) uniform samplerBuffer img;     // N×C×in_h×in_w, R32F
layout(binding = 1) uniform samplerBuffer coords;  // flow (R32F) or grid (RG32F)
layout(binding = 2) uniform samplerBuffer d_out;   // N×C×out_h×out_w, R32F
layout(std430, binding = 3) readonly buffer MaxAbs { uint max_abs_bits[]; };
layout(std430, binding = 4) buffer Acc { uint acc[]; };  // (lo, hi) per d_img element
layout(std430, binding = 5) writeonly buffer DCoords { float d_coords[]; };

void add_fixed(uint element, float value, int s) {
  const float scaled = scale_pow2(value, s);
  const float a = abs(scaled);
  // Exact split of |scaled| < 2^61 into 32-bit words (see the note above).
  const float hi_f = floor(a * (1.0 / 4294967296.0));
  uint lo = uint(round(a - hi_f * 4294967296.0));
  uint hi = uint(hi_f);
  if (scaled < 0.0) {
    lo = ~lo + 1u;
    hi = ~hi + (lo == 0u ? 1u : 0u);
  }
  if ((lo | hi) == 0u) return;
  const uint old = atomicAdd(acc[2u * element], lo);
  const uint carry = old + lo < old ? 1u : 0u;
  const uint hi_add = hi + carry;
  if (hi_add != 0u) atomicAdd(acc[2u * element + 1u], hi_add);
}

void main() {
  const uint plane_out = pc.out_h * pc.out_w;
  const uint gid = linear_group() * 128u + gl_LocalInvocationID.x;
  if (gid >= pc.n_batch * plane_out) return;
  const uint n = gid / plane_out, p = gid % plane_out;
  vec2 dpos;
  const vec2 pos = sample_position(coords, n, p, dpos);
  const Taps t = make_taps(pos, dpos);
  const uint plane_in = pc.in_h * pc.in_w;
  const float w[4] = float[4](t.wx0 * t.wy0, t.wx1 * t.wy0, t.wx0 * t.wy1, t.wx1 * t.wy1);
  int s = 0;
  bool scatter = kWantImage && t.finite;
  if (kWantImage) {
    const uint m_bits = max_abs_bits[0];
    s = fixed_scale_exp(m_bits);
    scatter = scatter && m_bits < 0x7f800000u;
  }
  vec2 grad = vec2(0.0);
  uint in_base = n * pc.channels * plane_in;
  uint out_index = n * pc.channels * plane_out + p;
  for (uint c = 0u; c < pc.channels; ++c) {
    const float g = texelFetch(d_out, int(out_index)).r;
    if (kWantCoords) {
      const vec4 v = fetch_taps(img, int(in_base), t);
      grad.x += g * (t.wy0 * (v[1] - v[0]) + t.wy1 * (v[3] - v[2]));
      grad.y += g * (t.wx0 * (v[2] - v[0]) + t.wx1 * (v[3] - v[1]));
    }
    if (scatter && g != 0.0) {
      [[unroll]] for (int k = 0; k < 4; ++k) {
        if (t.valid[k]) add_fixed(in_base + uint(t.idx[k]), w[k] * g, s);
      }
    }
    in_base += plane_in;
    out_index += plane_out;
  }
  if (kWantCoords) {
    grad = t.finite ? grad * t.dpos : vec2(kNaN);
    if (kGridMode == 0u) {
      d_coords[2u * n * plane_out + p] = grad.x;
      d_coords[(2u * n + 1u) * plane_out + p] = grad.y;
    } else {
      d_coords[2u * gid] = grad.x;
      d_coords[2u * gid + 1u] = grad.y;
    }
  }
}
