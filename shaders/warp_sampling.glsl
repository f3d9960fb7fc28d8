// Bilinear sampling at per-pixel positions, shared by warp_sample.comp and
// warp_sample_backward.comp (kernels/warp.cpp and kernels/grid_sample.cpp).
//
// Positions come either from a displacement field in pixels (warp: flow
// N×2×H×W, pos = (x + dx, y + dy)) or from a normalized grid (grid_sample:
// grid N×Hout×Wout×2 in [-1, 1], x then y, PyTorch semantics). Padding:
// zeros (out-of-range taps read 0) or border (the position is clamped to
// [0, size - 1] first, with zero gradient where it was clamped, as PyTorch's
// clip_coordinates_set_grad).
#ifndef VKJR2_WARP_SAMPLING_GLSL
#define VKJR2_WARP_SAMPLING_GLSL

#include "common.glsl"

// 0: positions from a pixel displacement field (warp); 1: from a normalized grid.
layout(constant_id = 0) const uint kGridMode = 0u;

layout(push_constant) uniform Push {
  uint n_batch;
  uint channels;
  uint in_h;
  uint in_w;
  uint out_h;
  uint out_w;
  uint padding;        // 0 zeros, 1 border
  uint align_corners;  // grid mode only
  uint count_log2;     // ceil(log2(out_h * out_w)): bound for the fixed-point d_img scatter
} pc;

#define kNaN uintBitsToFloat(0x7fc00000u)

// The four taps of one bilinear sample of an in_h × in_w plane.
struct Taps {
  ivec4 idx;   // plane offsets of (x0,y0) (x1,y0) (x0,y1) (x1,y1), clamped in range
  bvec4 valid;  // tap lies inside the plane (else it reads 0)
  float wx0, wx1, wy0, wy1;
  vec2 dpos;       // d pos / d coordinate (unnormalize scale × clip gradient)
  bool finite;     // the position was finite; otherwise outputs are NaN
};

// Position (in input pixels) and d pos / d coord for output pixel p of batch n.
// coords is the flow (R32F texel buffer) or the grid (RG32F texel buffer).
vec2 sample_position(samplerBuffer coords, uint n, uint p, out vec2 dpos) {
  const uint plane = pc.out_h * pc.out_w;
  const vec2 size = vec2(float(pc.in_w), float(pc.in_h));
  if (kGridMode == 0u) {
    const float x = float(p % pc.out_w), y = float(p / pc.out_w);
    const float dx = texelFetch(coords, int(2u * n * plane + p)).r;
    const float dy = texelFetch(coords, int((2u * n + 1u) * plane + p)).r;
    dpos = vec2(1.0);
    return vec2(x + dx, y + dy);
  }
  const vec2 g = texelFetch(coords, int(n * plane + p)).rg;
  // PyTorch grid_sampler_unnormalize, rounded as PyTorch's fp32 kernel
  // rounds it (precise: no FMA contraction).
  precise vec2 pos;
  if (pc.align_corners != 0u) {
    dpos = (size - 1.0) * 0.5;
    pos = (g + 1.0) * dpos;
  } else {
    dpos = size * 0.5;
    pos = ((g + 1.0) * size - 1.0) * 0.5;
  }
  return pos;
}

Taps make_taps(vec2 pos, vec2 dpos) {
  Taps t;
  const vec2 size = vec2(float(pc.in_w), float(pc.in_h));
  // abs(NaN) < x is false: NaN and ±inf positions are flagged and replaced.
  t.finite = all(lessThan(abs(pos), vec2(1e30)));
  pos = t.finite ? pos : vec2(0.0);
  if (pc.padding == 1u) {
    const vec2 hi = size - 1.0;
    dpos *= vec2(greaterThan(pos, vec2(0.0))) * vec2(lessThan(pos, hi));
    pos = clamp(pos, vec2(0.0), hi);
  } else {
    // Beyond one pixel outside, every tap is out of range anyway; the clamp
    // keeps the float → int conversion defined.
    pos = clamp(pos, vec2(-2.0), size + 1.0);
  }
  const vec2 f = floor(pos);
  const vec2 frac = pos - f;
  const ivec2 i0 = ivec2(f);
  const int w = int(pc.in_w), h = int(pc.in_h);
  const bool vx0 = i0.x >= 0 && i0.x < w, vx1 = i0.x + 1 >= 0 && i0.x + 1 < w;
  const bool vy0 = i0.y >= 0 && i0.y < h, vy1 = i0.y + 1 >= 0 && i0.y + 1 < h;
  const int cx0 = clamp(i0.x, 0, w - 1), cx1 = clamp(i0.x + 1, 0, w - 1);
  const int cy0 = clamp(i0.y, 0, h - 1), cy1 = clamp(i0.y + 1, 0, h - 1);
  t.idx = ivec4(cy0 * w + cx0, cy0 * w + cx1, cy1 * w + cx0, cy1 * w + cx1);
  t.valid = bvec4(vx0 && vy0, vx1 && vy0, vx0 && vy1, vx1 && vy1);
  t.wx1 = frac.x;
  t.wx0 = 1.0 - frac.x;
  t.wy1 = frac.y;
  t.wy0 = 1.0 - frac.y;
  t.dpos = dpos;
  return t;
}

// The four tap values of plane `base` (out-of-range taps read 0).
vec4 fetch_taps(samplerBuffer img, int base, Taps t) {
  const vec4 v = vec4(texelFetch(img, base + t.idx.x).r, texelFetch(img, base + t.idx.y).r,
                      texelFetch(img, base + t.idx.z).r, texelFetch(img, base + t.idx.w).r);
  return mix(vec4(0.0), v, t.valid);
}

float interpolate(vec4 v, Taps t) {
  return t.wy0 * (t.wx0 * v[0] + t.wx1 * v[1]) + t.wy1 * (t.wx0 * v[2] + t.wx1 * v[3]);
}

// 2^e for integer e in [-126, 127], exact.
float pow2(int e) { return intBitsToFloat((e + 127) << 23); }

// Exponent s of the fixed-point scale 2^s used by the d_img scatter: with
// m = max |d_out| < 2^e and at most 2^count_log2 contributions of weight ≤ 1
// per input element, every partial sum stays below 2^61 in magnitude.
int fixed_scale_exp(uint max_abs_bits) {
  int e;
  frexp(uintBitsToFloat(max_abs_bits), e);
  return 61 - int(pc.count_log2) - e;
}

// x · 2^s for s in [-252, 252] without overflowing the power of two.
float scale_pow2(float x, int s) {
  const int a = s / 2;
  return (x * pow2(a)) * pow2(s - a);
}

#endif
