#version 450
// conv2d forward, depthwise (groups == cin, cout = cin · multiplier): each
// invocation computes RY rows × PX consecutive pixels of one output channel
// (kernels/conv2d.cpp, depthwise_tile), from the zero-padded input of
// conv2d_pad or a producer's padded output (no bounds checks). Invocations
// run over (pixel block, channel) flattened, so small planes with many
// channels still fill whole workgroups. With RY > 1 (stride 1) the RY + KH − 1
// input rows of a block are loaded once; the KH·KW weights are read once per
// block. XRELU: ReLU on the input as it is loaded (relu(0) keeps the zero
// padding). y: hout × wout planes, or a padded tensor's (its consumer's input).
#define CONV2D_RESIDUAL
#include "common.glsl"
#include "conv2d_common.glsl"
layout(local_size_x_id = 7) in;  // 8..64: fewer lanes per group on small outputs
layout(constant_id = 0) const uint KH = 3u;
layout(constant_id = 1) const uint KW = 3u;
layout(constant_id = 2) const uint SX = 1u;
layout(constant_id = 3) const uint DX = 1u;
layout(constant_id = 4) const uint PX = 8u;
layout(constant_id = 5) const uint RY = 1u;  // output rows per invocation (RY > 1: sy = dy = 1)
layout(constant_id = 6) const uint XRELU = 0u;
// Zero columns before the left padding (kernels/conv2d.cpp, BlockedTile::sh):
// a block's taps start SH columns into its 4-aligned row segment.
layout(constant_id = 9) const uint SH = 0u;
// y stored by quads of pixels, one vec4 each (llvmpipe runs stores lane by
// lane). 1: PX and wout multiples of 4 and y's rows 4-aligned (yw, yleft).
// 2: y plain (hout × wout planes) and a block is whole rows (PX == wout, ox0
// == 0), so its RY · PX outputs are contiguous: RY · PX, hout · wout
// multiples of 4 and hout a multiple of RY (every block full).
layout(constant_id = 10) const uint STORE4 = 0u;
// The weights through an RGBA32F view (cout · KH · KW a multiple of 4): a
// channel's KH·KW taps in (KH·KW + 6) / 4 texel fetches instead of KH·KW,
// each tap picked from the texels by the channel's offset (selects).
layout(constant_id = 11) const uint WVEC4 = 0u;
const uint SEG = (PX - 1u) * SX + (KW - 1u) * DX + 1u + SH;
const uint SEG4 = (SEG + 3u) / 4u;  // as vec4 texels (rows start 4-aligned: wp % 4 == 0)
const uint NR = RY + KH - 1u;       // input rows of one block
const uint NT = KH * KW;
const uint NWT = (NT + 6u) / 4u;  // WVEC4: texels holding a channel's taps at any offset

layout(binding = 0) uniform samplerBuffer xp;      // RGBA32F: [n, cin, hp, wp], zero-padded
layout(binding = 1) uniform samplerBuffer weight;  // [cout, 1, kh, kw]; RGBA32F view when WVEC4
layout(binding = 2) uniform samplerBuffer bias;
layout(std430, binding = 3) writeonly buffer Y { float y[]; };
layout(std430, binding = 3) writeonly buffer Y4 { vec4 y4[]; };  // the same buffer (STORE4)

vec4 load(int i) {
  const vec4 v = texelFetch(xp, i);
  return XRELU != 0u ? max(v, vec4(0.0)) : v;
}

void main() {
  const uint rblocks = (pc.hout + RY - 1u) / RY;
  const uint npb = rblocks * pc.wblocks;
  const uint idx = linear_group() * gl_WorkGroupSize.x + gl_LocalInvocationID.x;
  const uint co = idx / npb;
  if (co >= pc.cout) return;
  const uint pb = idx - co * npb;
  const uint n = gl_WorkGroupID.z;
  const uint ci = co / pc.cout_g;
  const uint oy0 = (pb / pc.wblocks) * RY;
  const uint ox0 = (pb % pc.wblocks) * PX;

  float acc[RY * PX];  // acc[q · PX + p]
  const int xbase = int((((n * pc.cin + ci) * pc.hp + oy0 * pc.sy) * pc.wp + ox0 * SX) / 4u);
  const int wbase = int(co * KH * KW);
  // Every input row and tap weight first, then each output's KH·KW taps at
  // once: one accumulator live at a time, so fewer values spilled to the
  // stack (2–3 % less CPU time over the landmark net).
  const int row_step = int(pc.dy * pc.wp / 4u);  // RY > 1 needs sy = dy = 1
  vec4 r[NR * SEG4];  // row i: output row q, tap ky with q + ky = i
  [[unroll]] for (uint i = 0u; i < NR; ++i) {
    [[unroll]] for (uint j = 0u; j < SEG4; ++j) {
      r[i * SEG4 + j] = load(xbase + int(i) * row_step + int(j));
    }
  }
  float wv[NT];
  if (WVEC4 != 0u) {
    vec4 wt[NWT];
    [[unroll]] for (uint i = 0u; i < NWT; ++i) wt[i] = texelFetch(weight, wbase / 4 + int(i));
    const uint o = uint(wbase) % 4u;
    [[unroll]] for (uint t = 0u; t < NT; ++t) {
      const float w0 = wt[t / 4u][t % 4u], w1 = wt[(t + 1u) / 4u][(t + 1u) % 4u];
      const float w2 = wt[(t + 2u) / 4u][(t + 2u) % 4u], w3 = wt[(t + 3u) / 4u][(t + 3u) % 4u];
      wv[t] = o == 0u ? w0 : (o == 1u ? w1 : (o == 2u ? w2 : w3));
    }
  } else {
    [[unroll]] for (uint t = 0u; t < NT; ++t) wv[t] = texelFetch(weight, wbase + int(t)).r;
  }
  [[unroll]] for (uint q = 0u; q < RY; ++q) {
    [[unroll]] for (uint p = 0u; p < PX; ++p) {
      float a = 0.0;
      [[unroll]] for (uint ky = 0u; ky < KH; ++ky) {
        [[unroll]] for (uint kx = 0u; kx < KW; ++kx) {
          const uint col = p * SX + kx * DX + SH;
          a = fma(r[(q + ky) * SEG4 + col / 4u][col % 4u], wv[ky * KW + kx], a);
        }
      }
      acc[q * PX + p] = a;
    }
  }
  const float b = pc.has_bias != 0u ? texelFetch(bias, int(co)).r : 0.0;
  if (STORE4 == 2u) {
    const uint q0 = ((n * pc.cout + co) * pc.hout + oy0) * pc.wout / 4u;
    [[unroll]] for (uint j = 0u; j < RY * PX / 4u; ++j) {
      vec4 v;
      [[unroll]] for (uint k = 0u; k < 4u; ++k) {
        const uint e = 4u * j + k;  // output (oy0 + e / PX, e % PX)
        v[k] = conv_act(acc[e] + b + conv_residual(n, co, (oy0 + e / PX) * pc.wout + e % PX));
      }
      y4[q0 + j] = v;
    }
    return;
  }
  // A padded y may end before the output does (its consumer reads no further).
  const uint plane = (n * pc.cout + co) * pc.yh;
  [[unroll]] for (uint q = 0u; q < RY; ++q) {
    const uint oy = oy0 + q;
    if (oy >= pc.hout || oy + pc.ytop >= pc.yh) continue;
    const uint orow = (plane + oy + pc.ytop) * pc.yw + pc.yleft;
    if (STORE4 != 0u) {
      [[unroll]] for (uint p4 = 0u; p4 < PX; p4 += 4u) {
        const uint ox = ox0 + p4;
        if (ox < pc.wout && ox + pc.yleft < pc.yw) {
          vec4 v;
          [[unroll]] for (uint k = 0u; k < 4u; ++k) {
            v[k] = conv_act(acc[q * PX + p4 + k] + b + conv_residual(n, co, oy * pc.wout + ox + k));
          }
          y4[(orow + ox) / 4u] = v;
        }
      }
      continue;
    }
    [[unroll]] for (uint p = 0u; p < PX; ++p) {
      const uint ox = ox0 + p;
      if (ox < pc.wout && ox + pc.yleft < pc.yw) {
        y[orow + ox] = conv_act(acc[q * PX + p] + b + conv_residual(n, co, oy * pc.wout + ox));
      }
    }
  }
}
