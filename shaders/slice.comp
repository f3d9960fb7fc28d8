#version 450
// Generic NCHW region copy behind pad, slice, concat and their backwards:
// writes channels [c_dst0, c_dst0 + cw) of y (all pixels); the value at
// (n, c, i, j) is x[n, c - c_dst0 + c_src0, i + off_y, j + off_x] where that
// lies inside x, else `fill`. 4 consecutive pixels of one row per invocation.
#include "common.glsl"
layout(local_size_x = 256) in;
layout(binding = 0) uniform samplerBuffer x;
layout(std430, binding = 1) writeonly buffer Y { float y[]; };
layout(push_constant) uniform Push {
  uint n; int ci; int hi; int wi; int co; int ho; int wo;
  int c_src0; int c_dst0; int cw; int off_y; int off_x; float fill;
  uvec2 blocks_magic; uvec2 ho_magic; uvec2 cw_magic;
} pc;


void main() {
  const uint blocks_x = (uint(pc.wo) + 3u) / 4u;
  const uint item = linear_group() * 256u + gl_LocalInvocationID.x;
  if (item >= pc.n * uint(pc.cw * pc.ho) * blocks_x) return;
  const uint row = fast_div(item, pc.blocks_magic);  // (n * cw + c) * ho + i
  const int j0 = int(item - row * blocks_x) * 4;
  const uint nc = fast_div(row, pc.ho_magic);
  const int i = int(row - nc * uint(pc.ho));
  const int n = int(fast_div(nc, pc.cw_magic));
  const int c = int(nc) - n * pc.cw;
  const int si = i + pc.off_y;
  const bool row_inside = si >= 0 && si < pc.hi;
  const int src_row = ((n * pc.ci + c + pc.c_src0) * pc.hi + si) * pc.wi + pc.off_x;
  const int dst_row = ((n * pc.co + c + pc.c_dst0) * pc.ho + i) * pc.wo;
  [[unroll]] for (int k = 0; k < 4; ++k) {
    const int j = j0 + k;
    if (j >= pc.wo) break;
    const int sj = j + pc.off_x;
    float v = pc.fill;
    if (row_inside && sj >= 0 && sj < pc.wi) v = texelFetch(x, src_row + j).r;
    y[dst_row + j] = v;
  }
}
