// One radix-RADIX pass of a batched mixed-radix Stockham FFT (autosort: no
// bit reversal; every pass reads one buffer and writes the other).
// Included by fft_rR.comp, which defines RADIX. The host side is
// kernels/fft.cpp, which documents the push constants and the pass list.
//
// Pass (Stockham, decimation in time), transform length n, p = product of
// the radices of the earlier passes, nr = n / RADIX, butterfly j in [0, nr):
//   k = j mod p,  q = j / p
//   u_r = x[j + r nr] · w_n^(r k n / (p RADIX))        r = 0 .. RADIX-1
//   y[q p RADIX + k + r p] = DFT_RADIX(u)_r
// with w_n = exp(-2πi / n) from a double-precision host table. Only the
// forward transform is computed; the inverse is conj(F(conj(x))), the
// conjugations folded into the first load (in_im_sign) and the last store
// (out_scale).
#ifndef VKJR2_FFT_COMMON_GLSL
#define VKJR2_FFT_COMMON_GLSL

#include "common.glsl"

layout(local_size_x = 64) in;
// Complex data as RG32F texels; real input (r2c) bound as R32F, whose texels
// read back as (x, 0): the widening to complex costs nothing.
layout(binding = 0) uniform samplerBuffer src;
layout(binding = 1) uniform samplerBuffer twiddles;  // RG32F, w_n^t for t in [0, n)
layout(std430, binding = 2) writeonly buffer Dst { float dst[]; };

layout(push_constant) uniform Push {
  uint count;        // butterflies in this dispatch: outer · nr · inner
  uint n;            // transform length
  uint nr;           // n / RADIX
  uint p;            // product of the radices of the earlier passes
  uint tw_step;      // n / (p · RADIX)
  uint inner;        // transforms interleaved at unit stride (columns); 1 for rows
  uvec2 div_inner;   // magic numbers dividing by inner, nr and p
  uvec2 div_nr;
  uvec2 div_p;
  uint in_stride;    // texels between consecutive elements of one transform
  uint in_outer;     // texels between consecutive groups of `inner` transforms
  uint out_stride;   // the same for the output, in complex (or real) elements
  uint out_outer;
  uint in_len;       // elements i >= in_len read conj(x[n - i]) (Hermitian half input)
  uint out_len;      // elements i >= out_len are not stored (half spectrum output)
  uint out_real;     // 1: store the real part only (c2r output)
  float in_im_sign;  // -1: conjugate on load
  vec2 out_scale;    // multiplies the stored value (im < 0: conjugate)
} pc;

// Unsigned division by an invariant divisor d, exact for every 32-bit n
// (Granlund & Montgomery 1994, Fig. 4.1): m.x = magic, m.y = sh1 | sh2 << 8.
uint fast_div32(uint num, uvec2 m) {
  uint hi, lo;
  umulExtended(num, m.x, hi, lo);
  return (hi + ((num - hi) >> (m.y & 0xffu))) >> (m.y >> 8u);
}

vec2 cmul(vec2 a, vec2 b) { return vec2(a.x * b.x - a.y * b.y, a.x * b.y + a.y * b.x); }
vec2 mul_i(vec2 a) { return vec2(-a.y, a.x); }

// exp(-2πi t / R), t in [0, R).
const vec2 kW3[3] = vec2[](vec2(1.0, 0.0), vec2(-0.5, -0.8660254037844386),
                           vec2(-0.5, 0.8660254037844386));
const vec2 kW5[5] = vec2[](vec2(1.0, 0.0), vec2(0.30901699437494745, -0.9510565162951535),
                           vec2(-0.8090169943749475, -0.5877852522924731),
                           vec2(-0.8090169943749475, 0.5877852522924731),
                           vec2(0.30901699437494745, 0.9510565162951535));
const vec2 kW7[7] = vec2[](vec2(1.0, 0.0), vec2(0.6234898018587336, -0.7818314824680298),
                           vec2(-0.22252093395631440, -0.9749279121818236),
                           vec2(-0.9009688679024191, -0.4338837391175582),
                           vec2(-0.9009688679024191, 0.4338837391175582),
                           vec2(-0.22252093395631440, 0.9749279121818236),
                           vec2(0.6234898018587336, 0.7818314824680298));
const float kS2 = 0.70710678118654752;
const float kC16 = 0.92387953251128676;
const float kS16 = 0.38268343236508977;
const vec2 kW8[8] = vec2[](vec2(1.0, 0.0), vec2(kS2, -kS2), vec2(0.0, -1.0), vec2(-kS2, -kS2),
                           vec2(-1.0, 0.0), vec2(-kS2, kS2), vec2(0.0, 1.0), vec2(kS2, kS2));
const vec2 kW16[16] = vec2[](vec2(1.0, 0.0), vec2(kC16, -kS16), vec2(kS2, -kS2),
                             vec2(kS16, -kC16), vec2(0.0, -1.0), vec2(-kS16, -kC16),
                             vec2(-kS2, -kS2), vec2(-kC16, -kS16), vec2(-1.0, 0.0),
                             vec2(-kC16, kS16), vec2(-kS2, kS2), vec2(-kS16, kC16),
                             vec2(0.0, 1.0), vec2(kS16, kC16), vec2(kS2, kS2),
                             vec2(kC16, kS16));

const vec2 kW32[32] = vec2[](vec2(1, 0), vec2(0.98078528040323043, -0.19509032201612825),
                             vec2(0.92387953251128674, -0.38268343236508978), vec2(0.83146961230254524, -0.55557023301960218),
                             vec2(0.70710678118654757, -0.70710678118654746), vec2(0.55557023301960229, -0.83146961230254524),
                             vec2(0.38268343236508984, -0.92387953251128674), vec2(0.19509032201612833, -0.98078528040323043),
                             vec2(0, -1), vec2(-0.19509032201612819, -0.98078528040323043),
                             vec2(-0.38268343236508973, -0.92387953251128674), vec2(-0.55557023301960196, -0.83146961230254546),
                             vec2(-0.70710678118654746, -0.70710678118654757), vec2(-0.83146961230254535, -0.55557023301960218),
                             vec2(-0.92387953251128674, -0.38268343236508989), vec2(-0.98078528040323043, -0.19509032201612861),
                             vec2(-1, 0), vec2(-0.98078528040323043, 0.19509032201612836),
                             vec2(-0.92387953251128685, 0.38268343236508967), vec2(-0.83146961230254546, 0.55557023301960196),
                             vec2(-0.70710678118654768, 0.70710678118654746), vec2(-0.55557023301960218, 0.83146961230254524),
                             vec2(-0.38268343236509034, 0.92387953251128652), vec2(-0.19509032201612866, 0.98078528040323032),
                             vec2(0, 1), vec2(0.1950903220161283, 0.98078528040323043),
                             vec2(0.38268343236509, 0.92387953251128663), vec2(0.55557023301960184, 0.83146961230254546),
                             vec2(0.70710678118654735, 0.70710678118654768), vec2(0.83146961230254524, 0.55557023301960218),
                             vec2(0.92387953251128652, 0.38268343236509039), vec2(0.98078528040323032, 0.19509032201612872));

void dft2(inout vec2 a[2]) {
  const vec2 t = a[0];
  a[0] = t + a[1];
  a[1] = t - a[1];
}

void dft4(inout vec2 a[4]) {
  const vec2 t0 = a[0] + a[2], t1 = a[0] - a[2];
  const vec2 t2 = a[1] + a[3], t3 = -mul_i(a[1] - a[3]);
  a[0] = t0 + t2;
  a[2] = t0 - t2;
  a[1] = t1 + t3;
  a[3] = t1 - t3;
}

// Odd prime R: X_k = a0 + Σ_j t_j cos(2πjk/R) - i Σ_j d_j sin(2πjk/R) with
// t_j = a_j + a_{R-j}, d_j = a_j - a_{R-j}; X_{R-k} flips the sign of the
// sine sum.
#define VKJR2_DFT_ODD(R, TW)                                           \
  const vec2 x0 = a[0];                                                \
  vec2 total = a[0];                                                   \
  vec2 t[(R - 1) / 2], d[(R - 1) / 2];                                 \
  [[unroll]] for (int j = 1; j <= (R - 1) / 2; ++j) {                  \
    t[j - 1] = a[j] + a[R - j];                                        \
    d[j - 1] = a[j] - a[R - j];                                        \
    total += t[j - 1];                                                 \
  }                                                                    \
  [[unroll]] for (int k = 1; k <= (R - 1) / 2; ++k) {                  \
    vec2 m = x0, s = vec2(0.0);                                        \
    [[unroll]] for (int j = 1; j <= (R - 1) / 2; ++j) {                \
      const vec2 w = TW[(j * k) % R];                                  \
      m += w.x * t[j - 1];                                             \
      s += w.y * d[j - 1];                                             \
    }                                                                  \
    a[k] = m + mul_i(s);                                               \
    a[R - k] = m - mul_i(s);                                           \
  }                                                                    \
  a[0] = total;

void dft3(inout vec2 a[3]) { VKJR2_DFT_ODD(3, kW3) }
void dft5(inout vec2 a[5]) { VKJR2_DFT_ODD(5, kW5) }
void dft7(inout vec2 a[7]) { VKJR2_DFT_ODD(7, kW7) }

// R = A·B: n = B n1 + n2, k = k1 + A k2 (Cooley & Tukey 1965): A-point DFTs
// over n1, twiddles w_R^(n2 k1), B-point DFTs over n2.
#define VKJR2_DFT_COMPOSITE(R, A, B, DFTA, DFTB, TW)                   \
  vec2 y[R];                                                           \
  [[unroll]] for (int n2 = 0; n2 < B; ++n2) {                          \
    vec2 u[A];                                                         \
    [[unroll]] for (int n1 = 0; n1 < A; ++n1) u[n1] = a[B * n1 + n2];  \
    DFTA(u);                                                           \
    [[unroll]] for (int k1 = 0; k1 < A; ++k1) {                        \
      y[n2 * A + k1] = (n2 * k1) % R == 0 ? u[k1] : cmul(u[k1], TW[(n2 * k1) % R]); \
    }                                                                  \
  }                                                                    \
  [[unroll]] for (int k1 = 0; k1 < A; ++k1) {                          \
    vec2 v[B];                                                         \
    [[unroll]] for (int n2 = 0; n2 < B; ++n2) v[n2] = y[n2 * A + k1];  \
    DFTB(v);                                                           \
    [[unroll]] for (int k2 = 0; k2 < B; ++k2) a[k1 + A * k2] = v[k2];  \
  }

void dft8(inout vec2 a[8]) { VKJR2_DFT_COMPOSITE(8, 4, 2, dft4, dft2, kW8) }
void dft16(inout vec2 a[16]) { VKJR2_DFT_COMPOSITE(16, 4, 4, dft4, dft4, kW16) }
void dft32(inout vec2 a[32]) { VKJR2_DFT_COMPOSITE(32, 8, 4, dft8, dft4, kW32) }

#if RADIX == 1
void dft(inout vec2 a[1]) {}
#elif RADIX == 2
void dft(inout vec2 a[2]) { dft2(a); }
#elif RADIX == 3
void dft(inout vec2 a[3]) { dft3(a); }
#elif RADIX == 4
void dft(inout vec2 a[4]) { dft4(a); }
#elif RADIX == 5
void dft(inout vec2 a[5]) { dft5(a); }
#elif RADIX == 7
void dft(inout vec2 a[7]) { dft7(a); }
#elif RADIX == 8
void dft(inout vec2 a[8]) { dft8(a); }
#elif RADIX == 16
void dft(inout vec2 a[16]) { dft16(a); }
#elif RADIX == 32
void dft(inout vec2 a[32]) { dft32(a); }
#else
#error "unsupported RADIX"
#endif

void main() {
  const uint g = linear_group() * 64u + gl_LocalInvocationID.x;
  if (g >= pc.count) return;
  const uint t = fast_div32(g, pc.div_inner);
  const uint col = g - t * pc.inner;
  const uint outer = fast_div32(t, pc.div_nr);
  const uint j = t - outer * pc.nr;
  const uint q = fast_div32(j, pc.div_p);
  const uint k = j - q * pc.p;

  const uint in_base = outer * pc.in_outer + col;
  vec2 a[RADIX];
  [[unroll]] for (uint r = 0u; r < RADIX; ++r) {
    const uint i = j + r * pc.nr;
    const bool mirror = i >= pc.in_len;
    const vec2 v = texelFetch(src, int(in_base + (mirror ? pc.n - i : i) * pc.in_stride)).xy;
    a[r] = vec2(v.x, mirror ? -pc.in_im_sign * v.y : pc.in_im_sign * v.y);
  }
  if (pc.p > 1u) {
    const uint step = k * pc.tw_step;
    [[unroll]] for (uint r = 1u; r < RADIX; ++r) {
      a[r] = cmul(a[r], texelFetch(twiddles, int(r * step)).xy);
    }
  }
  dft(a);

  const uint out_base = outer * pc.out_outer + col;
  const uint o0 = q * pc.p * RADIX + k;
  if (pc.out_real != 0u) {
    [[unroll]] for (uint r = 0u; r < RADIX; ++r) {
      const uint o = o0 + r * pc.p;
      if (o < pc.out_len) dst[out_base + o * pc.out_stride] = a[r].x * pc.out_scale.x;
    }
  } else {
    [[unroll]] for (uint r = 0u; r < RADIX; ++r) {
      const uint o = o0 + r * pc.p;
      const uint at = 2u * (out_base + o * pc.out_stride);
      if (o < pc.out_len) {
        dst[at] = a[r].x * pc.out_scale.x;
        dst[at + 1u] = a[r].y * pc.out_scale.y;
      }
    }
  }
}

#endif
