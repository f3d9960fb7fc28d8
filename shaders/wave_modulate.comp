#version 450
// Split-step wave optics (sim/wave_optics.cpp): field[b, p] *= mask[p], and
// with a screen also *= exp(i φ(x + shift_b)): φ = the periodic FFT part of
// an M×M screen, bilinear with wrap-around, plus its subharmonic terms
// evaluated at the shifted position (they are not periodic). field [B, N, N]
// complex; mask [N, N] complex (absorber or transfer function); shifts [B]
// in pixels; terms (fx, fy in cycles per pixel, coefficient re, im) of the
// first levels, then 4 texels of the deeper levels' polynomial.
#include "common.glsl"
layout(local_size_x = 256) in;
layout(binding = 0) uniform samplerBuffer screens;  // R32F
layout(binding = 1) uniform samplerBuffer masks;    // RG32F
layout(binding = 2) uniform samplerBuffer shifts;   // RG32F
layout(binding = 3) uniform samplerBuffer terms;    // RGBA32F
layout(std430, binding = 4) buffer Field { vec2 field[]; };
layout(push_constant) uniform Push {
  uint n;              // N
  uint m;              // M (screen side, ≥ N)
  uint batch;          // B
  uint use_screen;     // 0: mask only
  uint screen_offset;  // texels
  uint mask_offset;    // texels
  uint shift_offset;   // texels
  uint term_offset;    // texels
  uint term_count;     // subharmonic terms of this screen
} pc;

const float kTwoPi = 6.28318530718;

float screen_at(int r, int c) {
  const int m = int(pc.m);
  r = r % m; r += r < 0 ? m : 0;
  c = c % m; c += c < 0 ? m : 0;
  return texelFetch(screens, int(pc.screen_offset) + r * m + c).r;
}

void main() {
  const uint i = linear_group() * 256u + gl_LocalInvocationID.x;
  const uint plane = pc.n * pc.n;
  if (i >= plane * pc.batch) return;
  const uint b = i / plane;
  const uint p = i - b * plane;
  const uint r = p / pc.n;
  const uint c = p - r * pc.n;
  vec2 k = texelFetch(masks, int(pc.mask_offset + p)).rg;
  if (pc.use_screen != 0u) {
    // Position in pixels from the centre sample (N/2 of the grid, M/2 of the screen).
    const vec2 s = texelFetch(shifts, int(pc.shift_offset + b)).rg;
    const float x = float(int(c) - int(pc.n / 2u)) + s.x;
    const float y = float(int(r) - int(pc.n / 2u)) + s.y;
    const float xs = x + float(pc.m / 2u), ys = y + float(pc.m / 2u);
    const float x0 = floor(xs), y0 = floor(ys);
    const float tx = xs - x0, ty = ys - y0;
    const int c0 = int(x0), r0 = int(y0);
    float phi = mix(mix(screen_at(r0, c0), screen_at(r0, c0 + 1), tx),
                    mix(screen_at(r0 + 1, c0), screen_at(r0 + 1, c0 + 1), tx), ty);
    for (uint t = 0u; t < pc.term_count; ++t) {
      const vec4 term = texelFetch(terms, int(pc.term_offset + t));
      const float theta = kTwoPi * (term.x * x + term.y * y);
      // Re(c (e^{iθ} − 1)), cos θ − 1 as −2 sin²(θ/2): no piston (Subharmonic).
      const float sh = sin(0.5 * theta);
      phi += -2.0 * term.z * sh * sh - term.w * sin(theta);
    }
    // The deeper levels: Σ a_k u^i v^(d−i) by degree d = 1..4, i = d..0, at
    // u = x/N, v = y/N (sim/wave_optics.cpp, subharmonic_polynomial).
    const uint q = pc.term_offset + pc.term_count;
    const vec4 a0 = texelFetch(terms, int(q)), a1 = texelFetch(terms, int(q + 1u));
    const vec4 a2 = texelFetch(terms, int(q + 2u)), a3 = texelFetch(terms, int(q + 3u));
    const float u = x / float(pc.n), v = y / float(pc.n);
    const float u2 = u * u, v2 = v * v, uv = u * v;
    phi += a0.x * u + a0.y * v;
    phi += a0.z * u2 + a0.w * uv + a1.x * v2;
    phi += a1.y * u2 * u + a1.z * u2 * v + a1.w * u * v2 + a2.x * v2 * v;
    phi += a2.y * u2 * u2 + a2.z * u2 * uv + a2.w * u2 * v2 + a3.x * uv * v2 + a3.y * v2 * v2;
    const vec2 e = vec2(cos(phi), sin(phi));
    k = vec2(k.x * e.x - k.y * e.y, k.x * e.y + k.y * e.x);
  }
  const vec2 f = field[i];
  field[i] = vec2(f.x * k.x - f.y * k.y, f.x * k.y + f.y * k.x);
}
