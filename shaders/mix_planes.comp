#version 450
// Crop the real parts of K complex planes and mix them point by point
// (kernels/mix.hpp): out[b, i, y, x] = scale · Σ_k mix[i, k] · Re planes[k·B + b][y, x];
// optionally first2[b, c, y, x] = first2_scale[c] · out[b, c, y, x], c < 2.
// One invocation per (point, batch item); the mix matrix is read through a
// texel buffer, the planes as RG32F texels.
#include "common.glsl"
layout(local_size_x = 64) in;
layout(binding = 0) uniform samplerBuffer planes;  // RG32F: (re, im) per texel
layout(binding = 1) uniform samplerBuffer mixm;    // R32F [K, K]
layout(std430, binding = 2) writeonly buffer Out { float o[]; };
layout(std430, binding = 3) writeonly buffer First2 { float f2[]; };
layout(push_constant) uniform Push {
  uint batch, k, plane_h, plane_w, out_h, out_w, write_first2;
  float scale, first2_x, first2_y;
} pc;

void main() {
  const uint p = gl_GlobalInvocationID.x;
  const uint b = gl_GlobalInvocationID.y;
  const uint points = pc.out_h * pc.out_w;
  if (p >= points) return;
  const uint y = p / pc.out_w;
  const uint x = p - y * pc.out_w;
  const uint plane_size = pc.plane_h * pc.plane_w;
  const uint at = y * pc.plane_w + x;
  const uint out_base = b * pc.k * points + p;
  for (uint i = 0u; i < pc.k; ++i) {
    float acc = 0.0;
    for (uint kk = 0u; kk < pc.k; ++kk) {
      const float m = texelFetch(mixm, int(i * pc.k + kk)).r;
      if (m != 0.0) acc = fma(m, texelFetch(planes, int((kk * pc.batch + b) * plane_size + at)).r, acc);
    }
    acc *= pc.scale;
    o[out_base + i * points] = acc;
    if (pc.write_first2 != 0u && i < 2u) {
      f2[(b * 2u + i) * points + p] = acc * (i == 0u ? pc.first2_x : pc.first2_y);
    }
  }
}
