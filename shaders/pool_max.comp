#version 450
// Max pool, NCHW. Each invocation computes 4 consecutive outputs of one row;
// padding taps are skipped (they act as -inf). NaN propagates (a NaN tap
// wins, as in PyTorch). Saves the flat in-plane index h*W + w of the maximum
// (INDICES; inference skips it). Windows up to 7×7 are specialization
// constants (KH, KW: unrolled), larger ones loop (KH = KW = 0). y is [planes, OH,
// OW] itself or the interior of a conv's zero-padded input (y_plane, y_row,
// y_offset).
#include "common.glsl"
layout(local_size_x = 256) in;
layout(constant_id = 0) const int KH = 3;  // 0: pc.kh
layout(constant_id = 1) const int KW = 3;  // 0: pc.kw
layout(constant_id = 2) const bool INDICES = true;
layout(binding = 0) uniform samplerBuffer x;
layout(std430, binding = 1) writeonly buffer Y { float y[]; };
layout(std430, binding = 2) writeonly buffer I { int indices[]; };
layout(push_constant) uniform Push {
  uint planes; int h; int w; int oh; int ow;
  int kh; int kw; int sh; int sw; int pad_top; int pad_left; int pad_bottom; int pad_right;
  uint flag;
  uvec2 blocks_magic; uvec2 rows_magic;  // divisors: blocks per row, rows per plane (written)
  uint y_plane, y_row, y_offset;         // y's layout (plain: OH·OW, OW, 0)
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
  const uint yo = plane * pc.y_plane + uint(oy) * pc.y_row + pc.y_offset;
  [[unroll]] for (int k = 0; k < 4; ++k) {
    const int ox = ox0 + k;
    if (ox >= pc.ow) break;
    const int xs = ox * pc.sw - pc.pad_left;
    float best = 0.0;
    int best_i = -1;
    const int kh = KH > 0 ? KH : pc.kh, kw = KW > 0 ? KW : pc.kw;
    [[unroll]] for (int ky = 0; ky < kh; ++ky) {
      const int iy = ys + ky;
      [[unroll]] for (int kx = 0; kx < kw; ++kx) {
        const int ix = xs + kx;
        if (iy < 0 || iy >= pc.h || ix < 0 || ix >= pc.w) continue;
        const int i = iy * pc.w + ix;
        const float v = texelFetch(x, plane_base + i).r;
        if (best_i < 0 || v > best || isnan(v)) {
          best = v;
          best_i = i;
        }
      }
    }
    y[yo + uint(ox)] = best;
    if (INDICES) indices[row * uint(pc.ow) + uint(ox)] = best_i;
  }
}
