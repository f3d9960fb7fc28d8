#version 450
// A network's input in one pass (kernels/resize.hpp, resize_into_padded):
// resize_zero_padded's forward (the same taps as resize.comp), then
// v·scale[c] + shift[c], written into the interior of a conv's zero-padded
// input (planes hp × wp, the out_h × out_w output at (top, left); the border
// is not written). FLAG: any NaN or infinite output sets flag[0] = 1 (the
// caller zero-fills it). Grid: x = blocks of 4 pixels of one output row
// (flattened with the rows), z = plane (image · channels + channel), so the
// channel is uniform per workgroup.
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

// The canvas at (yy, xx) of the plane starting at base: zero outside the source.
float canvas_at(int base, int yy, int xx) {
  const int sy = yy - pc.src_top, sx = xx - pc.src_left;
  const bool in_src = sy >= 0 && sy < pc.src_h && sx >= 0 && sx < pc.src_w;
  return in_src ? texelFetch(src, base + sy * pc.src_w + sx).r : 0.0;
}

void main() {
  const uint plane = gl_WorkGroupID.z;
  const uint blocks_x = (uint(pc.out_w) + 3u) / 4u;
  const uint item = linear_group() * gl_WorkGroupSize.x + gl_LocalInvocationID.x;
  if (item >= uint(pc.out_h) * blocks_x) return;
  const uint oy = fast_div(item, pc.blocks_magic);
  const int ox0 = int(item - oy * blocks_x) * 4;
  const int c = int(plane % pc.channels);
  const float s = texelFetch(scale, c).r, b = texelFetch(shift, c).r;
  const int base = int(plane) * pc.src_h * pc.src_w;
  int y0, y1;
  float ly;
  resize_taps(pc.mode, int(oy), pc.in_h, pc.scale_h, y0, y1, ly);
  vec4 v = vec4(0.0);
  [[unroll]] for (int k = 0; k < 4; ++k) {
    int x0, x1;
    float lx;
    resize_taps(pc.mode, min(ox0 + k, pc.out_w - 1), pc.in_w, pc.scale_w, x0, x1, lx);
    float r;
    if (NEAREST != 0u) {
      r = canvas_at(base, y0, x0);
    } else {
      const float top = (1.0 - lx) * canvas_at(base, y0, x0) + lx * canvas_at(base, y0, x1);
      const float bot = (1.0 - lx) * canvas_at(base, y1, x0) + lx * canvas_at(base, y1, x1);
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
  if (FLAG != 0u && (any(isnan(v)) || any(isinf(v)))) flag[0] = 1.0;
}
