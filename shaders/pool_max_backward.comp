#version 450
// Max pool backward as a gather: each input pixel sums dy over the windows
// that cover it and saved it as their argmax. Deterministic, no atomics.
// 4 consecutive input pixels of one row per invocation.
#include "common.glsl"
layout(local_size_x = 256) in;
layout(binding = 0) uniform samplerBuffer dy;
layout(binding = 1) uniform isamplerBuffer indices;
layout(std430, binding = 2) writeonly buffer DX { float dx[]; };
layout(push_constant) uniform Push {
  uint planes; int h; int w; int oh; int ow;
  int kh; int kw; int sh; int sw; int pad_top; int pad_left; int pad_bottom; int pad_right;
  uint flag;
  uvec2 blocks_magic; uvec2 rows_magic;  // divisors: blocks per row, rows per plane (written)
} pc;


// First window index whose extent [o*s - pad, o*s - pad + k) reaches p.
int first_window(int p, int pad, int k, int s) {
  const int a = p + pad - k + 1;
  return a <= 0 ? 0 : (a + s - 1) / s;
}

void main() {
  const uint blocks_x = (uint(pc.w) + 3u) / 4u;
  const uint item = linear_group() * 256u + gl_LocalInvocationID.x;
  if (item >= pc.planes * uint(pc.h) * blocks_x) return;
  const uint row = fast_div(item, pc.blocks_magic);  // plane * H + y
  const int x0 = int(item - row * blocks_x) * 4;
  const uint plane = fast_div(row, pc.rows_magic);
  const int iy = int(row - plane * uint(pc.h));
  const int out_base = int(plane) * pc.oh * pc.ow;
  const int oy0 = first_window(iy, pc.pad_top, pc.kh, pc.sh);
  const int oy1 = min(pc.oh - 1, (iy + pc.pad_top) / pc.sh);
  [[unroll]] for (int k = 0; k < 4; ++k) {
    const int ix = x0 + k;
    if (ix >= pc.w) break;
    const int ox0 = first_window(ix, pc.pad_left, pc.kw, pc.sw);
    const int ox1 = min(pc.ow - 1, (ix + pc.pad_left) / pc.sw);
    const int me = iy * pc.w + ix;
    float acc = 0.0;
    for (int oy = oy0; oy <= oy1; ++oy) {
      for (int ox = ox0; ox <= ox1; ++ox) {
        const int o = out_base + oy * pc.ow + ox;
        if (texelFetch(indices, o).r == me) acc += texelFetch(dy, o).r;
      }
    }
    dx[row * uint(pc.w) + uint(ix)] = acc;
  }
}
