#version 450
// Global average pool: one workgroup per (n, c) plane sums its H*W values
// (strided per invocation, then subgroup adds, then one shared step across
// subgroups; fixed order, deterministic) and writes the mean.
#extension GL_KHR_shader_subgroup_basic : require
#extension GL_KHR_shader_subgroup_arithmetic : require
#include "common.glsl"
layout(local_size_x = 256) in;
layout(binding = 0) uniform samplerBuffer x;
layout(std430, binding = 1) writeonly buffer Y { float y[]; };
layout(push_constant) uniform Push { uint planes; uint hw; } pc;

shared float subgroup_sums[256];

void main() {
  const uint plane = linear_group();
  if (plane >= pc.planes) return;  // uniform per workgroup
  const uint base = plane * pc.hw;
  float acc0 = 0.0, acc1 = 0.0, acc2 = 0.0, acc3 = 0.0;
  uint i = gl_LocalInvocationID.x;
  for (; i + 768u < pc.hw; i += 1024u) {
    acc0 += texelFetch(x, int(base + i)).r;
    acc1 += texelFetch(x, int(base + i + 256u)).r;
    acc2 += texelFetch(x, int(base + i + 512u)).r;
    acc3 += texelFetch(x, int(base + i + 768u)).r;
  }
  for (; i < pc.hw; i += 256u) acc0 += texelFetch(x, int(base + i)).r;
  float acc = subgroupAdd((acc0 + acc1) + (acc2 + acc3));
  if (subgroupElect()) subgroup_sums[gl_SubgroupID] = acc;
  barrier();
  if (gl_SubgroupID == 0u) {
    float total = 0.0;
    for (uint s = gl_SubgroupInvocationID; s < gl_NumSubgroups; s += gl_SubgroupSize) {
      total += subgroup_sums[s];
    }
    total = subgroupAdd(total);
    if (subgroupElect()) y[plane] = total / float(pc.hw);
  }
}
