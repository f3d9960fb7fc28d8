#version 450
// conv2d forward, 1×1 kernel, stride 1, no padding, groups == 1: a matmul
// y[n] = W · x[n] over the flattened h·w pixels. Each invocation computes 8
// output channels × 8 consecutive pixels; weights packed as in conv2d_blocked.
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
const uint PX = 8u;
layout(binding = 0) uniform samplerBuffer x;       // [n, cin, h·w]; RGBA32F view when VEC4
layout(binding = 1) uniform samplerBuffer packed;  // RGBA32F: [cout/8][cin][2]
layout(binding = 2) uniform samplerBuffer bias;
layout(std430, binding = 3) writeonly buffer Y { float y[]; };
layout(std430, binding = 3) writeonly buffer Y4 { vec4 y4[]; };  // the same buffer (STORE4)

vec4 a0[PX], a1[PX];  // output channels 0..3 and 4..7 of the block, per pixel
int pix[PX];          // !VEC4: the pixels (a last block's extra lanes re-read the last one)
int q0, q1;           // VEC4: the two quads of pixels

// One input channel: its plane at xbase, its 8 weights w0 (channels 0..3), w1.
void accumulate(int xbase, vec4 w0, vec4 w1) {
  if (VEC4 != 0u) {
    const vec4 v0 = texelFetch(x, xbase + q0);
    const vec4 v1 = texelFetch(x, xbase + q1);
    [[unroll]] for (uint p = 0u; p < 4u; ++p) {
      a0[p] = fma(vec4(v0[p]), w0, a0[p]);
      a1[p] = fma(vec4(v0[p]), w1, a1[p]);
      a0[p + 4u] = fma(vec4(v1[p]), w0, a0[p + 4u]);
      a1[p + 4u] = fma(vec4(v1[p]), w1, a1[p + 4u]);
    }
  } else {
    [[unroll]] for (uint p = 0u; p < PX; ++p) {
      const float v = texelFetch(x, xbase + pix[p]).r;
      a0[p] = fma(vec4(v), w0, a0[p]);
      a1[p] = fma(vec4(v), w1, a1[p]);
    }
  }
}

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
  const uint cob = idx / npb;  // block of 8 output channels
  if (cob >= (pc.cout + 7u) / 8u) return;
  const uint pix0 = (idx - cob * npb) * PX;
  const uint n = gl_WorkGroupID.z;
  [[unroll]] for (uint p = 0u; p < PX; ++p) {
    a0[p] = vec4(0.0);
    a1[p] = vec4(0.0);
  }
  int stride;  // one input channel's plane, in texels
  if (VEC4 != 0u) {
    const int quads = int(hw / 4u);
    q0 = int(pix0 / 4u);
    q1 = min(q0 + 1, quads - 1);  // a last block of 4 pixels re-reads its quad
    stride = quads;
  } else {
    [[unroll]] for (uint p = 0u; p < PX; ++p) pix[p] = int(min(pix0 + p, hw - 1u));
    stride = int(hw);
  }
  int xbase = int(n * pc.cin) * stride;
  int wi = int(cob * pc.cin * 2u);
  for (uint c = 0u; c < pc.cin; ++c) {
    accumulate(xbase, texelFetch(packed, wi), texelFetch(packed, wi + 1));
    xbase += stride;
    wi += 2;
  }

  float b[8];
  [[unroll]] for (uint j = 0u; j < 8u; ++j) {
    const uint co = cob * 8u + j;
    b[j] = (pc.has_bias != 0u && co < pc.cout) ? texelFetch(bias, int(co)).r : 0.0;
  }
  // A padded y may end before the output does (its consumer reads no further).
  const uint yplane = pc.yh * pc.yw;
  const uint ybase = (n * pc.cout + cob * 8u) * yplane;
  uint oy = pix0 / pc.w, ox = pix0 - oy * pc.w;  // of pixel pix0 + p (one division)
  if (STORE4 != 0u) {
    [[unroll]] for (uint h = 0u; h < 2u; ++h) {
      const uint qy = oy, qx = ox;  // the quad's first pixel
      vec4 v[8];                    // its 8 channels
      [[unroll]] for (uint p = 0u; p < 4u; ++p) {
        const uint q = 4u * h + p;
        if (p > 0u && ++ox == pc.w) {
          ox = 0u;
          ++oy;
        }
        [[unroll]] for (uint j = 0u; j < 4u; ++j) {
          v[j][p] = a0[q][j] + b[j];
          v[4u + j][p] = a1[q][j] + b[4u + j];
          if (RES4 == 0u) {
            v[j][p] += conv_residual_at(n, cob * 8u + j, oy, ox);
            v[4u + j][p] += conv_residual_at(n, cob * 8u + 4u + j, oy, ox);
          }
        }
      }
      if (++ox == pc.w) {  // to the next quad
        ox = 0u;
        ++oy;
      }
      [[unroll]] for (uint j = 0u; j < 8u; ++j) {
        if (RES4 != 0u) v[j] += residual_quad(n, cob * 8u + j, pix0 + 4u * h, qy, qx);
        [[unroll]] for (uint p = 0u; p < 4u; ++p) v[j][p] = conv_act(v[j][p]);
      }
      if (pix0 + 4u * h < hw && qy + pc.ytop < pc.yh && qx + pc.yleft < pc.yw) {
        const uint o = (ybase + (qy + pc.ytop) * pc.yw + qx + pc.yleft) / 4u;
        [[unroll]] for (uint j = 0u; j < 8u; ++j) {
          if (cob * 8u + j < pc.cout) y4[o + j * (yplane / 4u)] = v[j];
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
      [[unroll]] for (uint j = 0u; j < 4u; ++j) {
        const uint c0 = cob * 8u + j, c1 = c0 + 4u;
        if (c0 < pc.cout) {
          y[o + j * yplane] = conv_act(a0[p][j] + b[j] + conv_residual_at(n, c0, oy, ox));
        }
        if (c1 < pc.cout) {
          y[o + (4u + j) * yplane] =
              conv_act(a1[p][j] + b[4u + j] + conv_residual_at(n, c1, oy, ox));
        }
      }
    }
  }
}
