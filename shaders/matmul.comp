#version 450
// C[P, Q] = Σ_r A(p, r) · B(r, q) (+ bias[q]) with strided operands
// A(p, r) = a[p·a_sp + r·a_sr] and B(r, q) = b[r·b_sr + q·b_sq], so one shader
// serves Y = X·W, dX = dY·Wᵀ and dW = Xᵀ·dY. Register blocking: each
// invocation computes a 4 × 8 tile (8 vec4 accumulators, 12 texel fetches per
// 32 FMAs; TM and BVEC4 below), the r loop unrolled by 4; no shared memory
// (LAVAPIPE.md). Edge tiles clamp their reads into range and skip the
// out-of-range writes.
#include "common.glsl"
layout(local_size_x_id = 0) in;  // 8..64: fewer lanes per group on small products
layout(binding = 0) uniform samplerBuffer a;
layout(binding = 1) uniform samplerBuffer b;
layout(binding = 2) uniform samplerBuffer bias;
layout(std430, binding = 3) writeonly buffer C { float c[]; };
layout(push_constant) uniform Push {
  uint p_len, q_len, r_len;
  uint a_sp, a_sr, b_sr, b_sq;
  uint tiles_q;
  uint has_bias;
} pc;

// Rows per tile: 4, or 1 when C has fewer than 4 rows (a linear layer on
// one input: the clamped rows would repeat every fetch 4×).
layout(constant_id = 1) const uint TM = 4u;
// B read as vec4 texels (an RGBA32F view, 2 fetches for a tile's 8 columns
// instead of 8): b_sq == 1, b_sr and q_len multiples of 4 and 8.
layout(constant_id = 2) const uint BVEC4 = 0u;
const uint TN = 8u;

// Row r's 8 columns of the tile starting at column q0.
void b_row(uint rb, uint q0, uint bi[TN], out vec4 b0, out vec4 b1) {
  if (BVEC4 != 0u) {
    const int t = int((rb + q0) / 4u);
    b0 = texelFetch(b, t);
    b1 = texelFetch(b, t + 1);
    return;
  }
  b0 = vec4(texelFetch(b, int(rb + bi[0])).r, texelFetch(b, int(rb + bi[1])).r,
            texelFetch(b, int(rb + bi[2])).r, texelFetch(b, int(rb + bi[3])).r);
  b1 = vec4(texelFetch(b, int(rb + bi[4])).r, texelFetch(b, int(rb + bi[5])).r,
            texelFetch(b, int(rb + bi[6])).r, texelFetch(b, int(rb + bi[7])).r);
}

void main() {
  const uint tile = linear_group() * gl_WorkGroupSize.x + gl_LocalInvocationID.x;
  const uint tp = tile / pc.tiles_q, tq = tile - tp * pc.tiles_q;
  const uint p0 = tp * TM, q0 = tq * TN;
  if (p0 >= pc.p_len) return;
  uint ai[TM];
  [[unroll]] for (uint i = 0u; i < TM; ++i) ai[i] = min(p0 + i, pc.p_len - 1u) * pc.a_sp;
  uint bi[TN];
  [[unroll]] for (uint j = 0u; j < TN; ++j) bi[j] = min(q0 + j, pc.q_len - 1u) * pc.b_sq;
  vec4 acc[TM][2];
  [[unroll]] for (uint i = 0u; i < TM; ++i) acc[i][0] = acc[i][1] = vec4(0.0);

  uint r = 0u;
  const uint r4 = pc.r_len & ~3u;
  for (; r < r4; r += 4u) {
    [[unroll]] for (uint u = 0u; u < 4u; ++u) {
      const uint ra = (r + u) * pc.a_sr, rb = (r + u) * pc.b_sr;
      vec4 b0, b1;
      b_row(rb, q0, bi, b0, b1);
      [[unroll]] for (uint i = 0u; i < TM; ++i) {
        const float av = texelFetch(a, int(ai[i] + ra)).r;
        acc[i][0] = fma(vec4(av), b0, acc[i][0]);
        acc[i][1] = fma(vec4(av), b1, acc[i][1]);
      }
    }
  }
  for (; r < pc.r_len; ++r) {
    const uint ra = r * pc.a_sr, rb = r * pc.b_sr;
    vec4 b0, b1;
    b_row(rb, q0, bi, b0, b1);
    [[unroll]] for (uint i = 0u; i < TM; ++i) {
      const float av = texelFetch(a, int(ai[i] + ra)).r;
      acc[i][0] = fma(vec4(av), b0, acc[i][0]);
      acc[i][1] = fma(vec4(av), b1, acc[i][1]);
    }
  }

  vec4 bv[2] = {vec4(0.0), vec4(0.0)};
  if (pc.has_bias != 0u) {
    [[unroll]] for (uint j = 0u; j < TN; ++j) {
      bv[j / 4u][j % 4u] = texelFetch(bias, int(min(q0 + j, pc.q_len - 1u))).r;
    }
  }
  [[unroll]] for (uint i = 0u; i < TM; ++i) {
    const uint p = p0 + i;
    if (p < pc.p_len) {
      const vec4 r0 = acc[i][0] + bv[0], r1 = acc[i][1] + bv[1];
      [[unroll]] for (uint j = 0u; j < TN; ++j) {
        if (q0 + j < pc.q_len) c[p * pc.q_len + q0 + j] = j < 4u ? r0[j] : r1[j - 4u];
      }
    }
  }
}
