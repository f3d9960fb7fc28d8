#version 450
// conv2d forward, 1×1 kernel, stride 1, no padding, groups == 1: a matmul
// y[n] = W · x[n] over the flattened h·w pixels. Each invocation computes 8
// output channels × 8 consecutive pixels; weights packed as in conv2d_blocked.
#define CONV2D_RESIDUAL
#include "common.glsl"
#include "conv2d_common.glsl"
layout(local_size_x = 64) in;
layout(constant_id = 0) const uint VEC4 = 0u;  // h·w % 4 == 0: pixels read as two vec4 texels
const uint PX = 8u;
layout(binding = 0) uniform samplerBuffer x;       // [n, cin, h·w]; RGBA32F view when VEC4
layout(binding = 1) uniform samplerBuffer packed;  // RGBA32F: [cout/8][cin][2]
layout(binding = 2) uniform samplerBuffer bias;
layout(std430, binding = 3) writeonly buffer Y { float y[]; };

void main() {
  const uint hw = pc.h * pc.w;
  const uint pix0 = gl_GlobalInvocationID.x * PX;
  if (pix0 >= hw) return;
  const uint cob = gl_WorkGroupID.y;
  const uint n = gl_WorkGroupID.z;
  vec4 a0[PX], a1[PX];
  [[unroll]] for (uint p = 0u; p < PX; ++p) {
    a0[p] = vec4(0.0);
    a1[p] = vec4(0.0);
  }
  int wi = int(cob * pc.cin * 2u);
  if (VEC4 != 0u) {
    const int quads = int(hw / 4u);
    const int q0 = int(pix0 / 4u);
    const int q1 = min(q0 + 1, quads - 1);  // a last block of 4 pixels re-reads its quad
    int xbase = int(n * pc.cin) * quads;
    for (uint c = 0u; c < pc.cin; ++c) {
      const vec4 w0 = texelFetch(packed, wi);
      const vec4 w1 = texelFetch(packed, wi + 1);
      const vec4 v0 = texelFetch(x, xbase + q0);
      const vec4 v1 = texelFetch(x, xbase + q1);
      [[unroll]] for (uint p = 0u; p < 4u; ++p) {
        a0[p] = fma(vec4(v0[p]), w0, a0[p]);
        a1[p] = fma(vec4(v0[p]), w1, a1[p]);
        a0[p + 4u] = fma(vec4(v1[p]), w0, a0[p + 4u]);
        a1[p + 4u] = fma(vec4(v1[p]), w1, a1[p + 4u]);
      }
      xbase += quads;
      wi += 2;
    }
  } else {
    int pix[PX];  // clamped: the last block's extra lanes re-read the last pixel
    [[unroll]] for (uint p = 0u; p < PX; ++p) pix[p] = int(min(pix0 + p, hw - 1u));
    int xbase = int(n * pc.cin * hw);
    for (uint c = 0u; c < pc.cin; ++c) {
      const vec4 w0 = texelFetch(packed, wi);
      const vec4 w1 = texelFetch(packed, wi + 1);
      [[unroll]] for (uint p = 0u; p < PX; ++p) {
        const float v = texelFetch(x, xbase + pix[p]).r;
        a0[p] = fma(vec4(v), w0, a0[p]);
        a1[p] = fma(vec4(v), w1, a1[p]);
      }
      xbase += int(hw);
      wi += 2;
    }
  }

  float b[8];
  [[unroll]] for (uint j = 0u; j < 8u; ++j) {
    const uint co = cob * 8u + j;
    b[j] = (pc.has_bias != 0u && co < pc.cout) ? texelFetch(bias, int(co)).r : 0.0;
  }
  const uint obase = (n * pc.cout + cob * 8u) * hw + pix0;
  [[unroll]] for (uint p = 0u; p < PX; ++p) {
    if (pix0 + p < hw) {
      [[unroll]] for (uint j = 0u; j < 4u; ++j) {
        const uint c0 = cob * 8u + j, c1 = c0 + 4u;
        if (c0 < pc.cout) {
          y[obase + j * hw + p] = conv_act(a0[p][j] + b[j] + conv_residual(n, c0, pix0 + p));
        }
        if (c1 < pc.cout) {
          y[obase + (4u + j) * hw + p] =
              conv_act(a1[p][j] + b[4u + j] + conv_residual(n, c1, pix0 + p));
        }
      }
    }
  }
}
