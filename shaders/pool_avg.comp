#version 450
// Average pool, NCHW, 4 consecutive outputs of one row per invocation.
// pc.flag = 1: count_include_pad (divisor = window area clipped to the padded
// image, PyTorch); 0: divisor = input pixels inside the window (TF SAME).
#include "common.glsl"
layout(local_size_x = 256) in;
layout(binding = 0) uniform samplerBuffer x;
layout(std430, binding = 1) writeonly buffer Y { float y[]; };
layout(push_constant) uniform Push {
  uint planes; int h; int w; int oh; int ow;
  int kh; int kw; int sh; int sw; int pad_top; int pad_left; int pad_bottom; int pad_right;
  uint flag;
  uvec2 blocks_magic; uvec2 rows_magic;  // divisors: blocks per row, rows per plane (written)
} pc;


void main() {
  const uint blocks_x = (uint(pc.ow) + 3u) / 4u;
  const uint item = linear_group() * 256u + gl_LocalInvocationID.x;
  if (item >= pc.planes * uint(pc.oh) * blocks_x) return;
  const uint row = fast_div(item, pc.blocks_magic);  // plane * OH + oy
  const int ox0 = int(item - row * blocks_x) * 4;
  const uint plane = fast_div(row, pc.rows_magic);
  const int oy = int(row - plane * uint(pc.oh));
  const int plane_base = int(plane) * pc.h * pc.w;
  const int ys = oy * pc.sh - pc.pad_top;
  const int y0 = max(ys, 0), y1 = min(ys + pc.kh, pc.h);
  const int pad_rows = min(ys + pc.kh, pc.h + pc.pad_bottom) - ys;
  [[unroll]] for (int k = 0; k < 4; ++k) {
    const int ox = ox0 + k;
    if (ox >= pc.ow) break;
    const int xs = ox * pc.sw - pc.pad_left;
    const int x0 = max(xs, 0), x1 = min(xs + pc.kw, pc.w);
    float acc = 0.0;
    for (int iy = y0; iy < y1; ++iy) {
      const int r = plane_base + iy * pc.w;
      for (int ix = x0; ix < x1; ++ix) acc += texelFetch(x, r + ix).r;
    }
    const int count = pc.flag != 0u ? pad_rows * (min(xs + pc.kw, pc.w + pc.pad_right) - xs)
                                    : (y1 - y0) * (x1 - x0);
    y[row * uint(pc.ow) + uint(ox)] = acc / float(count);
  }
}
