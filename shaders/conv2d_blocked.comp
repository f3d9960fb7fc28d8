#version 450
// conv2d forward, groups == 1: each invocation computes 4·CG output channels ×
// RY rows × PX consecutive output pixels (CG·RY·PX vec4 accumulators, ≤ 25).
// Invocations run over (pixel block, channel block) flattened, so small images
// with many channels still fill whole workgroups (llvmpipe runs 8 lanes at a
// time and pays per workgroup). The input is the zero-padded copy from
// conv2d_pad or a producer's padded output (no bounds checks in the loop);
// one row segment is loaded once per (channel, input row) as vec4 texels and
// reused across kx and the RY output rows. Weights are packed by conv2d_pack:
// 8 channels per tap as two vec4 texels; an invocation of 4 channels reads
// one of them. See LAVAPIPE.md: texel-buffer reads, no shared memory, several
// outputs per invocation. On lavapipe a weight texel fetch (the same address
// in every lane) costs about twice an input one, so the shapes pick (CG, RY)
// to read fewer weights per FMA (kernels/conv2d.cpp, blocked_tile).
#define CONV2D_RESIDUAL
#include "common.glsl"
#include "conv2d_common.glsl"
layout(local_size_x_id = 7) in;  // 8..64: fewer lanes per group on small outputs
layout(constant_id = 0) const uint KH = 3u;
layout(constant_id = 1) const uint KW = 3u;
layout(constant_id = 2) const uint SX = 1u;
layout(constant_id = 3) const uint DX = 1u;
layout(constant_id = 4) const uint PX = 8u;
layout(constant_id = 5) const uint CG = 2u;  // vec4 channel groups per invocation (1 or 2)
layout(constant_id = 6) const uint RY = 1u;  // output rows per invocation (RY > 1: sy = dy = 1)
// y stored by quads of pixels, one vec4 each (llvmpipe runs stores lane by
// lane, so 4× fewer store loops): PX, wout, yw and yleft multiples of 4.
layout(constant_id = 9) const uint STORE4 = 0u;
const uint SEG = (PX - 1u) * SX + (KW - 1u) * DX + 1u;  // input columns one row needs
const uint SEG4 = (SEG + 3u) / 4u;  // as vec4 texels (rows start 4-aligned: wp % 4 == 0)
const uint NR = RY + KH - 1u;       // input rows of one block when RY > 1

layout(binding = 0) uniform samplerBuffer xp;      // RGBA32F: [n, cin, hp, wp], zero-padded
layout(binding = 1) uniform samplerBuffer packed;  // RGBA32F: [cout/8][cin][kh][kw][2]
layout(binding = 2) uniform samplerBuffer bias;
layout(std430, binding = 3) writeonly buffer Y { float y[]; };
layout(std430, binding = 3) writeonly buffer Y4 { vec4 y4[]; };  // the same buffer (STORE4)

void main() {
  const uint rblocks = (pc.hout + RY - 1u) / RY;
  const uint npb = rblocks * pc.wblocks;
  const uint idx = linear_group() * gl_WorkGroupSize.x + gl_LocalInvocationID.x;
  const uint cob = idx / npb;  // block of 4·CG output channels
  if (cob >= (pc.cout + 4u * CG - 1u) / (4u * CG)) return;
  const uint pb = idx - cob * npb;
  const uint n = gl_WorkGroupID.z;
  const uint oy0 = (pb / pc.wblocks) * RY;
  const uint ox0 = (pb % pc.wblocks) * PX;
  const uint co0 = cob * 4u * CG;

  vec4 a[CG * RY * PX];  // a[(g · RY + r) · PX + p]
  [[unroll]] for (uint i = 0u; i < CG * RY * PX; ++i) a[i] = vec4(0.0);
  const int plane = int(pc.hp * pc.wp / 4u);
  // Input rows: dy apart (RY == 1), or consecutive (RY > 1 needs sy = dy = 1).
  const int row_step = int(pc.dy * pc.wp / 4u);
  int xbase = int((((n * pc.cin) * pc.hp + oy0 * pc.sy) * pc.wp + ox0 * SX) / 4u);
  // Packed texel of (channel block of 8, cin, tap, half): ((cb8·cin + c)·KH·KW + tap)·2 + half.
  int wbase = int((co0 / 8u) * pc.cin * KH * KW * 2u + (co0 % 8u) / 4u);
  // Per input channel: its NR input rows and KH·KW taps' weights are fetched
  // first, then each accumulator takes all its KH·KW taps at once. llvmpipe
  // keeps the accumulators on the stack (a load, a blend under the loop's
  // lane mask and a store per update), so one update per channel instead of
  // one per tap. The taps are summed in the same order as before.
  for (uint c = 0u; c < pc.cin; ++c) {
    vec4 r[NR * SEG4];  // input rows (row i: output row q, tap ky with q + ky = i)
    [[unroll]] for (uint i = 0u; i < NR; ++i) {
      [[unroll]] for (uint j = 0u; j < SEG4; ++j) {
        r[i * SEG4 + j] = texelFetch(xp, xbase + int(i) * row_step + int(j));
      }
    }
    vec4 w[KH * KW * CG];  // w[tap · CG + g]
    [[unroll]] for (uint t = 0u; t < KH * KW; ++t) {
      [[unroll]] for (uint g = 0u; g < CG; ++g) {
        w[t * CG + g] = texelFetch(packed, wbase + int(t * 2u + g));
      }
    }
    [[unroll]] for (uint g = 0u; g < CG; ++g) {
      [[unroll]] for (uint q = 0u; q < RY; ++q) {
        [[unroll]] for (uint p = 0u; p < PX; ++p) {
          vec4 acc = a[(g * RY + q) * PX + p];
          [[unroll]] for (uint ky = 0u; ky < KH; ++ky) {
            [[unroll]] for (uint kx = 0u; kx < KW; ++kx) {
              const uint col = p * SX + kx * DX;
              const float v = r[(q + ky) * SEG4 + col / 4u][col % 4u];
              acc = fma(vec4(v), w[(ky * KW + kx) * CG + g], acc);
            }
          }
          a[(g * RY + q) * PX + p] = acc;
        }
      }
    }
    xbase += plane;
    wbase += int(KH * KW * 2u);
  }

  // y: planes of yh × yw with the output at (ytop, yleft): hout × wout
  // itself, or the zero-padded input of the next conv (conv2d_padded_input).
  // A padded y may end before the output does (its consumer reads no further).
  const uint hw = pc.yh * pc.yw;
  [[unroll]] for (uint g = 0u; g < CG; ++g) {
    [[unroll]] for (uint j = 0u; j < 4u; ++j) {
      const uint co = co0 + g * 4u + j;
      if (co >= pc.cout) continue;
      const float b = pc.has_bias != 0u ? texelFetch(bias, int(co)).r : 0.0;
      [[unroll]] for (uint q = 0u; q < RY; ++q) {
        const uint oy = oy0 + q;
        if (oy >= pc.hout || oy + pc.ytop >= pc.yh) continue;
        const uint orow = (n * pc.cout + co) * hw + (oy + pc.ytop) * pc.yw + pc.yleft;
        if (STORE4 != 0u) {
          [[unroll]] for (uint p4 = 0u; p4 < PX; p4 += 4u) {
            const uint ox = ox0 + p4;
            if (ox < pc.wout && ox + pc.yleft < pc.yw) {
              vec4 v;
              [[unroll]] for (uint k = 0u; k < 4u; ++k) {
                v[k] = conv_act(a[(g * RY + q) * PX + p4 + k][j] + b +
                                conv_residual_at(n, co, oy, ox + k));
              }
              y4[(orow + ox) / 4u] = v;
            }
          }
          continue;
        }
        [[unroll]] for (uint p = 0u; p < PX; ++p) {
          const uint ox = ox0 + p;
          if (ox < pc.wout && ox + pc.yleft < pc.yw) {
            const float v = a[(g * RY + q) * PX + p][j] + b + conv_residual_at(n, co, oy, ox);
            y[orow + ox] = conv_act(v);
          }
        }
      }
    }
  }
}
