#version 450
// A network's input in one pass (kernels/resize.hpp, resize_into_padded):
// resize_zero_padded's forward (the same taps as resize.comp), then
// v·scale[c] + shift[c], written into the interior of a conv's zero-padded
// input (planes hp × wp, the out_h × out_w output at (top, left); the border
// is not written). FLAG: any NaN or infinite output sets flag[0] = 1 (the
// caller zero-fills it). Grid: x = blocks of 4 pixels of one output row
// (flattened with the rows), z = image; each invocation runs its 4 pixels
// through every channel, the taps computed once.
#include "common.glsl"
#include "resize_common.glsl"
layout(local_size_x_id = 3) in;                   // 8..64 (group_lanes)
layout(constant_id = 0) const uint NEAREST = 0u;  // mode 3 (one tap)
// The 4 pixels stored as one vec4 (llvmpipe runs stores lane by lane): out_w,
// wp and left multiples of 4.
layout(constant_id = 1) const uint STORE4 = 0u;
layout(constant_id = 2) const uint FLAG = 0u;
layout(binding = 0) uniform samplerBuffer src;    // x [N, C, src_h, src_w]
layout(binding = 1) uniform samplerBuffer scale;  // [C]
layout(binding = 2) uniform samplerBuffer shift;  // [C]
layout(std430, binding = 3) writeonly buffer Dst { float dst[]; };
layout(std430, binding = 3) writeonly buffer Dst4 { vec4 dst4[]; };  // the same buffer (STORE4)
layout(std430, binding = 4) writeonly buffer Flag { float flag[]; };
layout(push_constant) uniform Push {
  uint channels;
  int in_h, in_w;         // the canvas
  int out_h, out_w;       // the output
  uint mode;
  float scale_h, scale_w;
  uvec2 blocks_magic;     // divisor: blocks of 4 pixels per output row
  int src_h, src_w;       // the source planes
  int src_top, src_left;  // where they sit in the canvas
  uint hp, wp;            // the padded planes
  uint top, left;         // where the output sits in them
} pc;

void main() {
  const uint n = gl_WorkGroupID.z;
  const uint blocks_x = (uint(pc.out_w) + 3u) / 4u;
  const uint item = linear_group() * gl_WorkGroupSize.x + gl_LocalInvocationID.x;
  if (item >= uint(pc.out_h) * blocks_x) return;
  const uint oy = fast_div(item, pc.blocks_magic);
  const int ox0 = int(item - oy * blocks_x) * 4;
  // The taps, shared by the channels: source offsets within a plane, and
  // whether each lies in the source (the canvas is zero elsewhere).
  int y0, y1;
  float ly;
  resize_taps(pc.mode, int(oy), pc.in_h, pc.scale_h, y0, y1, ly);
  const int sy0 = y0 - pc.src_top, sy1 = y1 - pc.src_top;
  const bool in_y0 = sy0 >= 0 && sy0 < pc.src_h, in_y1 = sy1 >= 0 && sy1 < pc.src_h;
  int o00[4], o01[4], o10[4], o11[4];  // (row 0/1, column 0/1) of output k
  bool v00[4], v01[4], v10[4], v11[4];
  float lx[4];
  [[unroll]] for (int k = 0; k < 4; ++k) {
    int x0, x1;
    resize_taps(pc.mode, min(ox0 + k, pc.out_w - 1), pc.in_w, pc.scale_w, x0, x1, lx[k]);
    const int sx0 = x0 - pc.src_left, sx1 = x1 - pc.src_left;
    const bool in_x0 = sx0 >= 0 && sx0 < pc.src_w, in_x1 = sx1 >= 0 && sx1 < pc.src_w;
    v00[k] = in_y0 && in_x0;
    v01[k] = in_y0 && in_x1;
    v10[k] = in_y1 && in_x0;
    v11[k] = in_y1 && in_x1;
    o00[k] = v00[k] ? sy0 * pc.src_w + sx0 : 0;
    o01[k] = v01[k] ? sy0 * pc.src_w + sx1 : 0;
    o10[k] = v10[k] ? sy1 * pc.src_w + sx0 : 0;
    o11[k] = v11[k] ? sy1 * pc.src_w + sx1 : 0;
  }
  const int src_plane = pc.src_h * pc.src_w;
  bool bad = false;
  for (uint c = 0u; c < pc.channels; ++c) {
    const uint plane = n * pc.channels + c;
    const int base = int(plane) * src_plane;
    const float s = texelFetch(scale, int(c)).r, b = texelFetch(shift, int(c)).r;
    vec4 v;
    [[unroll]] for (int k = 0; k < 4; ++k) {
      const float a00 = v00[k] ? texelFetch(src, base + o00[k]).r : 0.0;
      float r;
      if (NEAREST != 0u) {
        r = a00;
      } else {
        const float a01 = v01[k] ? texelFetch(src, base + o01[k]).r : 0.0;
        const float a10 = v10[k] ? texelFetch(src, base + o10[k]).r : 0.0;
        const float a11 = v11[k] ? texelFetch(src, base + o11[k]).r : 0.0;
        // As resize.comp computes it.
        const float top = (1.0 - lx[k]) * a00 + lx[k] * a01;
        const float bot = (1.0 - lx[k]) * a10 + lx[k] * a11;
        r = (1.0 - ly) * top + ly * bot;
      }
      v[k] = fma(r, s, b);  // as channel_affine computes it
    }
    const uint row = (plane * pc.hp + oy + pc.top) * pc.wp + pc.left + uint(ox0);
    if (STORE4 != 0u) {
      dst4[row / 4u] = v;
    } else {
      [[unroll]] for (int k = 0; k < 4; ++k) {
        if (ox0 + k < pc.out_w) dst[row + uint(k)] = v[k];
      }
    }
    bad = bad || any(isnan(v)) || any(isinf(v));
  }
  if (FLAG != 0u && bad) flag[0] = 1.0;
}
