#version 450
// conv2d forward, groups == 1: each invocation computes 8 output channels × PX
// (8, or 4 on images at most 4 wide) consecutive output pixels of one row
// (2·PX vec4 accumulators). Invocations run over (pixel block, channel block)
// flattened, so small images with many channels still fill whole workgroups
// (llvmpipe runs 8 lanes at a time and pays per workgroup). The input is
// the zero-padded copy from conv2d_pad (no bounds checks in the loop); one row
// segment is loaded once per (channel, ky) as vec4 texels and reused across
// kx. Weights are packed by conv2d_pack: 8 channels per tap as two vec4
// texels. See LAVAPIPE.md: texel-buffer reads, no shared memory, several
// outputs per invocation. Measured on lavapipe (3×3 64→64 128²): scalar input
// reads 3.5–4 GFLOP/s, vec4 input reads 12–17; weights through a 64 KiB UBO
// (chunked dispatches) were slower than through this texel buffer.
#define CONV2D_RESIDUAL
#include "common.glsl"
#include "conv2d_common.glsl"
layout(local_size_x = 64) in;
layout(constant_id = 0) const uint KH = 3u;
layout(constant_id = 1) const uint KW = 3u;
layout(constant_id = 2) const uint SX = 1u;
layout(constant_id = 3) const uint DX = 1u;
layout(constant_id = 4) const uint PX = 8u;
const uint SEG = (PX - 1u) * SX + (KW - 1u) * DX + 1u;  // input columns one row needs
const uint SEG4 = (SEG + 3u) / 4u;  // as vec4 texels (rows start 4-aligned: wp % 4 == 0)

layout(binding = 0) uniform samplerBuffer xp;      // RGBA32F: [n, cin, hp, wp], zero-padded
layout(binding = 1) uniform samplerBuffer packed;  // RGBA32F: [cout/8][cin][kh][kw][2]
layout(binding = 2) uniform samplerBuffer bias;
layout(std430, binding = 3) writeonly buffer Y { float y[]; };

void main() {
  const uint npb = pc.hout * pc.wblocks;
  const uint idx = linear_group() * 64u + gl_LocalInvocationID.x;
  const uint cob = idx / npb;
  if (cob >= (pc.cout + 7u) / 8u) return;
  const uint pb = idx - cob * npb;
  const uint n = gl_WorkGroupID.z;
  const uint oy = pb / pc.wblocks;
  const uint ox0 = (pb % pc.wblocks) * PX;

  vec4 a0[PX], a1[PX];
  [[unroll]] for (uint p = 0u; p < PX; ++p) {
    a0[p] = vec4(0.0);
    a1[p] = vec4(0.0);
  }
  const int plane = int(pc.hp * pc.wp / 4u);
  const int row_step = int(pc.dy * pc.wp / 4u);
  int xbase = int((((n * pc.cin) * pc.hp + oy * pc.sy) * pc.wp + ox0 * SX) / 4u);
  int wbase = int(cob * pc.cin * KH * KW * 2u);
  for (uint c = 0u; c < pc.cin; ++c) {
    [[unroll]] for (uint ky = 0u; ky < KH; ++ky) {
      const int rb = xbase + int(ky) * row_step;
      vec4 r[SEG4];
      [[unroll]] for (uint j = 0u; j < SEG4; ++j) r[j] = texelFetch(xp, rb + int(j));
      [[unroll]] for (uint kx = 0u; kx < KW; ++kx) {
        const int wi = wbase + int((ky * KW + kx) * 2u);
        const vec4 w0 = texelFetch(packed, wi);
        const vec4 w1 = texelFetch(packed, wi + 1);
        [[unroll]] for (uint p = 0u; p < PX; ++p) {
          const float v = r[(p * SX + kx * DX) / 4u][(p * SX + kx * DX) % 4u];
          a0[p] = fma(vec4(v), w0, a0[p]);
          a1[p] = fma(vec4(v), w1, a1[p]);
        }
      }
    }
    xbase += plane;
    wbase += int(KH * KW * 2u);
  }

  float b[8];
  [[unroll]] for (uint j = 0u; j < 8u; ++j) {
    const uint co = cob * 8u + j;
    b[j] = (pc.has_bias != 0u && co < pc.cout) ? texelFetch(bias, int(co)).r : 0.0;
  }
  // y: planes of yh × yw with the output at (ytop, yleft): hout × wout
  // itself, or the zero-padded input of the next conv (conv2d_padded_input).
  const uint hw = pc.yh * pc.yw;
  const uint obase = (n * pc.cout + cob * 8u) * hw + (oy + pc.ytop) * pc.yw + ox0 + pc.yleft;
  // A padded y may end before the output does (its consumer reads no further).
  if (oy + pc.ytop >= pc.yh) return;
  [[unroll]] for (uint p = 0u; p < PX; ++p) {
    if (ox0 + p < pc.wout && ox0 + p + pc.yleft < pc.yw) {
      [[unroll]] for (uint j = 0u; j < 4u; ++j) {
        const uint c0 = cob * 8u + j, c1 = c0 + 4u;
        if (c0 < pc.cout) {
          y[obase + j * hw + p] = conv_act(a0[p][j] + b[j] + conv_residual_at(n, c0, oy, ox0 + p));
        }
        if (c1 < pc.cout) {
          y[obase + (4u + j) * hw + p] =
              conv_act(a1[p][j] + b[4u + j] + conv_residual_at(n, c1, oy, ox0 + p));
        }
      }
    }
  }
}
