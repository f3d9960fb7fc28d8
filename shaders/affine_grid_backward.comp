#version 450
// d_theta[n] = Σ_{h,w} d_grid[n, h, w] ⊗ (x_w, y_h, 1), the backward of
// affine_grid.comp. One workgroup per batch element: each invocation sums a
// fixed strided subset of pixels, then a fixed-order shared-memory tree adds
// the partial sums, so the result is deterministic.
#include "common.glsl"
layout(local_size_x = 256) in;
layout(binding = 0) uniform samplerBuffer d_grid;  // N×H×W×2, RG32F
layout(std430, binding = 1) writeonly buffer DTheta { float d_theta[]; };
layout(push_constant) uniform Push {
  uint n_batch;
  uint h;
  uint w;
  uint align_corners;
} pc;

shared float partial[6][256];

float base_coord(uint i, uint size) {
  if (size <= 1u) return 0.0;
  if (pc.align_corners != 0u) return -1.0 + 2.0 * float(i) / float(size - 1u);
  return (2.0 * float(i) + 1.0) / float(size) - 1.0;
}

void main() {
  const uint n = linear_group();
  if (n >= pc.n_batch) return;  // uniform per workgroup: barrier() below stays legal
  const uint lid = gl_LocalInvocationID.x;
  const uint plane = pc.h * pc.w;
  float acc[6] = float[6](0.0, 0.0, 0.0, 0.0, 0.0, 0.0);
  for (uint p = lid; p < plane; p += 256u) {
    const vec2 g = texelFetch(d_grid, int(n * plane + p)).rg;
    const float x = base_coord(p % pc.w, pc.w), y = base_coord(p / pc.w, pc.h);
    acc[0] += g.x * x;
    acc[1] += g.x * y;
    acc[2] += g.x;
    acc[3] += g.y * x;
    acc[4] += g.y * y;
    acc[5] += g.y;
  }
  [[unroll]] for (int k = 0; k < 6; ++k) partial[k][lid] = acc[k];
  barrier();
  for (uint stride = 128u; stride > 0u; stride >>= 1u) {
    if (lid < stride) {
      [[unroll]] for (int k = 0; k < 6; ++k) partial[k][lid] += partial[k][lid + stride];
    }
    barrier();
  }
  if (lid < 6u) d_theta[6u * n + lid] = partial[lid][0];
}
