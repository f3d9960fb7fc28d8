#version 450
// conv2d forward, 1×1 kernel, stride 1, no padding, groups == 1: a matmul
// y[n] = W · x[n] over the flattened h·w pixels. Each invocation computes CO
// (8 or 16) output channels × 8 consecutive pixels; weights packed as in
// conv2d_blocked (blocks of 8 channels).
// Invocations run over (pixel block, channel block) flattened, so small
// planes with many channels still fill whole workgroups. y: h × w planes, or
// a padded tensor's (its consumer's input); the residual plain or, has_res
// == 2, in a padded tensor's layout (hp, wp, pt, pl: a pointwise conv has no
// padding of its own).
#define CONV2D_RESIDUAL
#include "common.glsl"
#include "conv2d_common.glsl"
layout(local_size_x_id = 1) in;  // 8..64: fewer lanes per group on small outputs
layout(constant_id = 0) const uint VEC4 = 0u;  // h·w % 4 == 0: pixels read as two vec4 texels
// VEC4 and y stored by quads of pixels, one vec4 each (4× fewer stores, which
// llvmpipe runs lane by lane): y plain (a quad is contiguous even across a
// row end), or padded with w, yw and yleft multiples of 4 (a quad is 4
// aligned pixels of one row).
layout(constant_id = 2) const uint STORE4 = 0u;
// STORE4 and the residual read by quads as well (an RGBA32F view): plain, or
// padded with w, wp and pl multiples of 4.
layout(constant_id = 3) const uint RES4 = 0u;
layout(constant_id = 4) const uint PX = 8u;  // pixels per invocation, a multiple of 4
const uint NQ = PX / 4u;  // VEC4: quads of pixels
// Output channels per invocation: 8 or 16 (cout % 16 == 0), as NB vec4s.
layout(constant_id = 5) const uint CO = 8u;
const uint NB = CO / 4u;
// The input-channel loop unrolled by UNROLL (cin % UNROLL == 0).
layout(constant_id = 6) const uint UNROLL = 1u;
layout(binding = 0) uniform samplerBuffer x;       // [n, cin, h·w]; RGBA32F view when VEC4
layout(binding = 1) uniform samplerBuffer packed;  // RGBA32F: [cout/8][cin][2]
layout(binding = 2) uniform samplerBuffer bias;
layout(std430, binding = 3) writeonly buffer Y { float y[]; };
layout(std430, binding = 3) writeonly buffer Y4 { vec4 y4[]; };  // the same buffer (STORE4)

// Accumulators: acc[b · PX + p] holds output channels 4b..4b+3 of the
// block at pixel p.
vec4 acc[NB * PX];
int pix[PX];  // !VEC4: the pixels (a last block's extra lanes re-read the last one)
int q[NQ];    // VEC4: the quads of pixels

// RES4: the residual of channel co at the quad starting at flat pixel qpix,
// row qy, column qx.
vec4 residual_quad(uint n, uint co, uint qpix, uint qy, uint qx) {
  if (co >= pc.cres) return vec4(0.0);
  if (HAS_RES == 1u) return texelFetch(res, int(((n * pc.cres + co) * pc.h * pc.w + qpix) / 4u));
  const uint row = (n * pc.cres + co) * pc.hp + qy + uint(pc.pt);
  return texelFetch(res, int((row * pc.wp + qx + uint(pc.pl)) / 4u));
}

void main() {
  const uint hw = pc.h * pc.w;
  const uint npb = (hw + PX - 1u) / PX;
  const uint idx = linear_group() * gl_WorkGroupSize.x + gl_LocalInvocationID.x;
  const uint cob = idx / npb;  // block of CO output channels
  if (cob >= (pc.cout + CO - 1u) / CO) return;
  const uint pix0 = (idx - cob * npb) * PX;
  const uint n = gl_WorkGroupID.z;
  [[unroll]] for (uint i = 0u; i < NB * PX; ++i) acc[i] = vec4(0.0);
  int stride;  // one input channel's plane, in texels
  if (VEC4 != 0u) {
    const int quads = int(hw / 4u);
    // A last block's quads past the plane re-read its last quad.
    [[unroll]] for (uint h = 0u; h < NQ; ++h) q[h] = min(int(pix0 / 4u + h), quads - 1);
    stride = quads;
  } else {
    [[unroll]] for (uint p = 0u; p < PX; ++p) pix[p] = int(min(pix0 + p, hw - 1u));
    stride = int(hw);
  }
  int xbase = int(n * pc.cin) * stride;
  // Packed weights: [cout/8][cin][2] vec4; this block's 8-channel blocks are
  // cin · 2 texels apart.
  int wi = int(cob * (CO / 8u) * pc.cin * 2u);
  const int wstep = int(pc.cin * 2u);
  // Each step fetches UNROLL channels' weights and pixels first, then
  // updates each accumulator once with all of them: the CO · PX accumulators
  // live on the stack, and llvmpipe loads, updates (under the loop's lane
  // mask) and stores each one once per step instead of once per channel
  // (15–25 % less CPU time on the landmark net's shapes). The sums run in
  // channel order all the same.
  for (uint c = 0u; c < pc.cin; c += UNROLL) {
    vec4 w[UNROLL * NB];  // w[u · NB + b]: channel c + u's weights for outputs 4b..4b+3
    float v[UNROLL * PX];  // v[u · PX + p]: channel c + u at pixel p
    [[unroll]] for (uint u = 0u; u < UNROLL; ++u) {
      [[unroll]] for (uint b = 0u; b < NB; ++b) {
        w[u * NB + b] = texelFetch(packed, wi + int(b / 2u) * wstep + int(b % 2u));
      }
      wi += 2;
      if (VEC4 != 0u) {
        [[unroll]] for (uint h = 0u; h < NQ; ++h) {
          const vec4 t = texelFetch(x, xbase + q[h]);
          [[unroll]] for (uint p = 0u; p < 4u; ++p) v[u * PX + 4u * h + p] = t[p];
        }
      } else {
        [[unroll]] for (uint p = 0u; p < PX; ++p) v[u * PX + p] = texelFetch(x, xbase + pix[p]).r;
      }
      xbase += stride;
    }
    [[unroll]] for (uint p = 0u; p < PX; ++p) {
      [[unroll]] for (uint b = 0u; b < NB; ++b) {
        vec4 a = acc[b * PX + p];
        [[unroll]] for (uint u = 0u; u < UNROLL; ++u) a = fma(vec4(v[u * PX + p]), w[u * NB + b], a);
        acc[b * PX + p] = a;
      }
    }
  }

  const uint co0 = cob * CO;  // the block's first output channel
  float b[CO];
  [[unroll]] for (uint j = 0u; j < CO; ++j) {
    const uint co = co0 + j;
    b[j] = (pc.has_bias != 0u && co < pc.cout) ? texelFetch(bias, int(co)).r : 0.0;
  }
  // A padded y may end before the output does (its consumer reads no further).
  const uint yplane = pc.yh * pc.yw;
  const uint ybase = (n * pc.cout + co0) * yplane;
  uint oy = pix0 / pc.w, ox = pix0 - oy * pc.w;  // of pixel pix0 + p (one division)
  if (STORE4 != 0u) {
    [[unroll]] for (uint h = 0u; h < NQ; ++h) {
      const uint qy = oy, qx = ox;  // the quad's first pixel
      vec4 v[CO];                   // its CO channels
      [[unroll]] for (uint p = 0u; p < 4u; ++p) {
        const uint qp = 4u * h + p;
        if (p > 0u && ++ox == pc.w) {
          ox = 0u;
          ++oy;
        }
        [[unroll]] for (uint j = 0u; j < CO; ++j) {
          v[j][p] = acc[(j / 4u) * PX + qp][j % 4u] + b[j];
          if (RES4 == 0u) v[j][p] += conv_residual_at(n, co0 + j, oy, ox);
        }
      }
      if (++ox == pc.w) {  // to the next quad
        ox = 0u;
        ++oy;
      }
      [[unroll]] for (uint j = 0u; j < CO; ++j) {
        if (RES4 != 0u) v[j] += residual_quad(n, co0 + j, pix0 + 4u * h, qy, qx);
        [[unroll]] for (uint p = 0u; p < 4u; ++p) v[j][p] = conv_act(v[j][p]);
      }
      if (pix0 + 4u * h < hw && qy + pc.ytop < pc.yh && qx + pc.yleft < pc.yw) {
        const uint o = (ybase + (qy + pc.ytop) * pc.yw + qx + pc.yleft) / 4u;
        [[unroll]] for (uint j = 0u; j < CO; ++j) {
          if (co0 + j < pc.cout) y4[o + j * (yplane / 4u)] = v[j];
        }
      }
    }
    return;
  }
  [[unroll]] for (uint p = 0u; p < PX; ++p) {
    const uint pix = pix0 + p;
    if (p > 0u && ++ox == pc.w) {
      ox = 0u;
      ++oy;
    }
    if (pix < hw && oy + pc.ytop < pc.yh && ox + pc.yleft < pc.yw) {
      const uint o = ybase + (oy + pc.ytop) * pc.yw + ox + pc.yleft;
      [[unroll]] for (uint j = 0u; j < CO; ++j) {
        const uint co = co0 + j;
        if (co < pc.cout) {
          y[o + j * yplane] =
              conv_act(acc[(j / 4u) * PX + p][j % 4u] + b[j] + conv_residual_at(n, co, oy, ox));
        }
      }
    }
  }
}
