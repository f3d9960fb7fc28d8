#version 450
// Global average pool of small planes (H·W ≤ 64, e.g. the [1, 256, 2, 2]
// ResNet head): one invocation per (n, c) plane sums it in a fixed order (4
// partial sums), 64 planes per workgroup, no barriers. The workgroup-per-plane
// kernel (pool_global_avg) would idle most of its 256 invocations here and pay
// a barrier per plane.
#include "common.glsl"
layout(local_size_x = 64) in;
layout(binding = 0) uniform samplerBuffer x;
layout(std430, binding = 1) writeonly buffer Y { float y[]; };
layout(push_constant) uniform Push { uint planes; uint hw; } pc;

void main() {
  const uint plane = linear_group() * 64u + gl_LocalInvocationID.x;
  if (plane >= pc.planes) return;
  const int base = int(plane * pc.hw);
  float acc0 = 0.0, acc1 = 0.0, acc2 = 0.0, acc3 = 0.0;
  int i = 0;
  for (; i + 3 < int(pc.hw); i += 4) {
    acc0 += texelFetch(x, base + i).r;
    acc1 += texelFetch(x, base + i + 1).r;
    acc2 += texelFetch(x, base + i + 2).r;
    acc3 += texelFetch(x, base + i + 3).r;
  }
  for (; i < int(pc.hw); ++i) acc0 += texelFetch(x, base + i).r;
  y[plane] = ((acc0 + acc1) + (acc2 + acc3)) / float(pc.hw);
}
