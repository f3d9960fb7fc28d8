#version 450
// Bilinear / nearest resize of NCHW images (modes: see kernels/resize.hpp)
// and its adjoint. The forward samples an in_h × in_w canvas that holds the
// src_h × src_w source plane at (src_top, src_left) and zeros elsewhere (a
// plain resize: the canvas is the source; resize_zero_padded: pad, then
// resize, in one pass). BACKWARD = 0: each invocation computes 4 consecutive
// output pixels of one row. BACKWARD = 1: each invocation computes 4
// consecutive input-pixel gradients, gathering over the output pixels whose
// taps touch them (the same tap function as the forward, so the two agree
// exactly; no atomics, deterministic).
#include "common.glsl"
#include "resize_common.glsl"
layout(local_size_x = 256) in;
layout(constant_id = 0) const uint BACKWARD = 0u;
// pc.mode == 3 (nearest) as a specialization constant for the forward's taps:
// llvmpipe runs both sides of a branch on a push constant, so a runtime test
// would fetch the one nearest tap and the four bilinear ones for every output.
layout(constant_id = 1) const uint NEAREST = 0u;
layout(binding = 0) uniform samplerBuffer src;  // x (forward) or dy (backward)
layout(std430, binding = 1) writeonly buffer Dst { float dst[]; };  // y or dx
layout(push_constant) uniform Push {
  uint planes; int in_h; int in_w; int out_h; int out_w; uint mode; float scale_h; float scale_w;
  uvec2 blocks_magic; uvec2 rows_magic;  // divisors: blocks per row, rows per plane (written)
  int src_h; int src_w;                  // the source planes (forward; <= in_h, in_w)
  int src_top; int src_left;             // where they sit in the canvas
} pc;


// The taps of output coordinate d on one axis (shaders/resize_common.glsl).
void taps(int d, int n_in, float scale, out int i0, out int i1, out float l) {
  resize_taps(pc.mode, d, n_in, scale, i0, i1, l);
}

// First output coordinate whose taps reach input i or beyond: start from the
// inverse mapping, then correct it with the exact tap function.
int first_output(int i, int n_in, int n_out, float scale) {
  int d = 0;
  if (scale > 0.0) {
    const float t = pc.mode == 0u ? (float(i) - 0.5) / scale - 0.5 : float(i - 1) / scale;
    d = clamp(int(floor(t)), 0, n_out - 1);
  }
  int i0, i1;
  float l;
  for (;;) {  // step back while the previous output still reaches i
    if (d == 0) break;
    taps(d - 1, n_in, scale, i0, i1, l);
    if (i1 < i) break;
    --d;
  }
  for (;;) {  // step forward while this output stays below i
    if (d >= n_out) break;
    taps(d, n_in, scale, i0, i1, l);
    if (i1 >= i) break;
    ++d;
  }
  return d;
}

// The canvas at (yy, xx) of the plane starting at base: zero outside the source.
float canvas_at(int base, int yy, int xx) {
  const int sy = yy - pc.src_top, sx = xx - pc.src_left;
  const bool in_src = sy >= 0 && sy < pc.src_h && sx >= 0 && sx < pc.src_w;
  return in_src ? texelFetch(src, base + sy * pc.src_w + sx).r : 0.0;
}

void forward_pass(uint item) {
  const uint blocks_x = (uint(pc.out_w) + 3u) / 4u;
  if (item >= pc.planes * uint(pc.out_h) * blocks_x) return;
  const uint row = fast_div(item, pc.blocks_magic);  // plane * out_h + oy
  const int ox0 = int(item - row * blocks_x) * 4;
  const uint plane = fast_div(row, pc.rows_magic);
  const int oy = int(row - plane * uint(pc.out_h));
  const int base = int(plane) * pc.src_h * pc.src_w;
  int y0, y1;
  float ly;
  taps(oy, pc.in_h, pc.scale_h, y0, y1, ly);
  [[unroll]] for (int k = 0; k < 4; ++k) {
    const int ox = ox0 + k;
    if (ox >= pc.out_w) break;
    int x0, x1;
    float lx;
    taps(ox, pc.in_w, pc.scale_w, x0, x1, lx);
    if (NEAREST != 0u) {  // one tap
      dst[row * uint(pc.out_w) + uint(ox)] = canvas_at(base, y0, x0);
      continue;
    }
    const float top = (1.0 - lx) * canvas_at(base, y0, x0) + lx * canvas_at(base, y0, x1);
    const float bot = (1.0 - lx) * canvas_at(base, y1, x0) + lx * canvas_at(base, y1, x1);
    dst[row * uint(pc.out_w) + uint(ox)] = (1.0 - ly) * top + ly * bot;
  }
}

void backward_pass(uint item) {
  const uint blocks_x = (uint(pc.in_w) + 3u) / 4u;
  if (item >= pc.planes * uint(pc.in_h) * blocks_x) return;
  const uint row = fast_div(item, pc.blocks_magic);  // plane * in_h + iy
  const int ix0 = int(item - row * blocks_x) * 4;
  const uint plane = fast_div(row, pc.rows_magic);
  const int iy = int(row - plane * uint(pc.in_h));
  const int base = int(plane) * pc.out_h * pc.out_w;
  const int oy_first = first_output(iy, pc.in_h, pc.out_h, pc.scale_h);
  [[unroll]] for (int k = 0; k < 4; ++k) {
    const int ix = ix0 + k;
    if (ix >= pc.in_w) break;
    const int ox_first = first_output(ix, pc.in_w, pc.out_w, pc.scale_w);
    float acc = 0.0;
    for (int oy = oy_first; oy < pc.out_h; ++oy) {
      int a0, a1;
      float al;
      taps(oy, pc.in_h, pc.scale_h, a0, a1, al);
      if (a0 > iy) break;
      const float wy = (a0 == iy ? 1.0 - al : 0.0) + (a1 == iy ? al : 0.0);
      float acc_row = 0.0;
      for (int ox = ox_first; ox < pc.out_w; ++ox) {
        int b0, b1;
        float bl;
        taps(ox, pc.in_w, pc.scale_w, b0, b1, bl);
        if (b0 > ix) break;
        const float wx = (b0 == ix ? 1.0 - bl : 0.0) + (b1 == ix ? bl : 0.0);
        acc_row += wx * texelFetch(src, base + oy * pc.out_w + ox).r;
      }
      acc += wy * acc_row;
    }
    dst[row * uint(pc.in_w) + uint(ix)] = acc;
  }
}

void main() {
  const uint item = linear_group() * 256u + gl_LocalInvocationID.x;
  if (BACKWARD != 0u) {
    backward_pass(item);
  } else {
    forward_pass(item);
  }
}
