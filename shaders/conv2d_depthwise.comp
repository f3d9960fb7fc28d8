#version 450
// conv2d forward, depthwise (groups == cin, cout = cin · multiplier): each
// invocation computes 8 consecutive output pixels of one row of one output
// channel, from the zero-padded input of conv2d_pad (no bounds checks).
#define CONV2D_RESIDUAL
#include "common.glsl"
#include "conv2d_common.glsl"
layout(local_size_x = 64) in;
layout(constant_id = 0) const uint KH = 3u;
layout(constant_id = 1) const uint KW = 3u;
layout(constant_id = 2) const uint SX = 1u;
layout(constant_id = 3) const uint DX = 1u;
const uint PX = 8u;
const uint SEG = (PX - 1u) * SX + (KW - 1u) * DX + 1u;
const uint SEG4 = (SEG + 3u) / 4u;  // as vec4 texels (rows start 4-aligned: wp % 4 == 0)

layout(binding = 0) uniform samplerBuffer xp;      // RGBA32F: [n, cin, hp, wp], zero-padded
layout(binding = 1) uniform samplerBuffer weight;  // [cout, 1, kh, kw]
layout(binding = 2) uniform samplerBuffer bias;
layout(std430, binding = 3) writeonly buffer Y { float y[]; };

void main() {
  const uint pb = gl_GlobalInvocationID.x;
  if (pb >= pc.hout * pc.wblocks) return;
  const uint co = gl_WorkGroupID.y;
  const uint n = gl_WorkGroupID.z;
  const uint ci = co / pc.cout_g;
  const uint oy = pb / pc.wblocks;
  const uint ox0 = (pb % pc.wblocks) * PX;

  float acc[PX];
  [[unroll]] for (uint p = 0u; p < PX; ++p) acc[p] = 0.0;
  const int xbase = int((((n * pc.cin + ci) * pc.hp + oy * pc.sy) * pc.wp + ox0 * SX) / 4u);
  const int row_step = int(pc.dy * pc.wp / 4u);
  const int wbase = int(co * KH * KW);
  [[unroll]] for (uint ky = 0u; ky < KH; ++ky) {
    const int rb = xbase + int(ky) * row_step;
    vec4 r[SEG4];
    [[unroll]] for (uint j = 0u; j < SEG4; ++j) r[j] = texelFetch(xp, rb + int(j));
    [[unroll]] for (uint kx = 0u; kx < KW; ++kx) {
      const float wv = texelFetch(weight, wbase + int(ky * KW + kx)).r;
      [[unroll]] for (uint p = 0u; p < PX; ++p) {
        const uint k = p * SX + kx * DX;
        acc[p] = fma(r[k / 4u][k % 4u], wv, acc[p]);
      }
    }
  }
  const float b = pc.has_bias != 0u ? texelFetch(bias, int(co)).r : 0.0;
  const uint obase = ((n * pc.cout + co) * pc.hout + oy) * pc.wout + ox0;
  [[unroll]] for (uint p = 0u; p < PX; ++p) {
    if (ox0 + p < pc.wout) {
      y[obase + p] = conv_act(acc[p] + b + conv_residual(n, co, oy * pc.wout + ox0 + p));
    }
  }
}
