#version 450
// conv2d backward-weight, groups == 1: each invocation owns one (input
// channel, ky) and 8 output channels, i.e. dw[co0..co0+7, ci, ky, 0..KW-1],
// and sums over every n, output row and 8-pixel block. Both operands are
// zero-padded copies (conv2d_pad): x with the forward's geometry, dy with rows
// rounded up to whole 8-pixel blocks, so the loop has no bounds checks and
// reads vec4 texels only.
#include "common.glsl"
#include "conv2d_common.glsl"
layout(local_size_x = 64) in;
layout(constant_id = 0) const uint KW = 3u;
layout(constant_id = 1) const uint SX = 1u;
layout(constant_id = 2) const uint DX = 1u;
const uint PX = 8u;
const uint SEG = (PX - 1u) * SX + (KW - 1u) * DX + 1u;
const uint SEG4 = (SEG + 3u) / 4u;

layout(binding = 0) uniform samplerBuffer xp;   // RGBA32F view of [n, cin, hp, wp]
layout(binding = 1) uniform samplerBuffer dyp;  // RGBA32F view of [n, cout, hout, wblocks·8]
layout(std430, binding = 2) writeonly buffer DW { float dw[]; };

void main() {
  const uint i = gl_GlobalInvocationID.x;
  if (i >= pc.cin * pc.kh) return;
  const uint ci = i / pc.kh;
  const uint ky = i % pc.kh;
  const uint co0 = gl_WorkGroupID.y * 8u;
  const uint dq = pc.wblocks * 2u;  // vec4s per padded dy row
  int dy_chan[8];                   // channel offsets; channels past cout re-read the last
  [[unroll]] for (uint j = 0u; j < 8u; ++j) {
    dy_chan[j] = int(min(co0 + j, pc.cout - 1u) * pc.hout * dq);
  }
  float acc[8u * KW];
  [[unroll]] for (uint k = 0u; k < 8u * KW; ++k) acc[k] = 0.0;
  for (uint n = 0u; n < pc.n; ++n) {
    for (uint oy = 0u; oy < pc.hout; ++oy) {
      int xrow = int((((n * pc.cin + ci) * pc.hp + oy * pc.sy + ky * pc.dy) * pc.wp) / 4u);
      int drow = int((n * pc.cout * pc.hout + oy) * dq);
      for (uint b = 0u; b < pc.wblocks; ++b) {
        vec4 r[SEG4];
        [[unroll]] for (uint s = 0u; s < SEG4; ++s) r[s] = texelFetch(xp, xrow + int(s));
        [[unroll]] for (uint j = 0u; j < 8u; ++j) {
          const vec4 d0 = texelFetch(dyp, drow + dy_chan[j]);
          const vec4 d1 = texelFetch(dyp, drow + dy_chan[j] + 1);
          [[unroll]] for (uint kx = 0u; kx < KW; ++kx) {
            float a = acc[j * KW + kx];
            [[unroll]] for (uint p = 0u; p < 4u; ++p) {
              a = fma(d0[p], r[(p * SX + kx * DX) / 4u][(p * SX + kx * DX) % 4u], a);
              a = fma(d1[p], r[((p + 4u) * SX + kx * DX) / 4u][((p + 4u) * SX + kx * DX) % 4u], a);
            }
            acc[j * KW + kx] = a;
          }
        }
        xrow += int(2u * SX);  // 8 output pixels = 8·SX input columns
        drow += 2;
      }
    }
  }
  [[unroll]] for (uint j = 0u; j < 8u; ++j) {
    if (co0 + j < pc.cout) {
      const uint base = (((co0 + j) * pc.cin + ci) * pc.kh + ky) * KW;
      [[unroll]] for (uint kx = 0u; kx < KW; ++kx) dw[base + kx] = acc[j * KW + kx];
    }
  }
}
