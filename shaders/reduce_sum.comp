#version 450
// One pass of a sum: each workgroup adds 2048 consecutive elements (8 per
// invocation) into partial[group]. Subgroup adds, then one shared-memory step
// across subgroups; fixed order, so the result is deterministic per device.
#extension GL_KHR_shader_subgroup_basic : require
#extension GL_KHR_shader_subgroup_arithmetic : require
#include "common.glsl"
layout(local_size_x = 256) in;
layout(binding = 0) uniform samplerBuffer x;
layout(std430, binding = 1) writeonly buffer Partial { float partial[]; };
layout(push_constant) uniform Push { uint n; } pc;

shared float subgroup_sums[256];

void main() {
  const uint group = linear_group();
  const uint base = group * 2048u + gl_LocalInvocationID.x;
  float acc = 0.0;
  [[unroll]] for (uint k = 0u; k < 8u; ++k) {
    const uint i = base + k * 256u;
    if (i < pc.n) acc += texelFetch(x, int(i)).r;
  }
  acc = subgroupAdd(acc);
  if (subgroupElect()) subgroup_sums[gl_SubgroupID] = acc;
  barrier();
  if (gl_SubgroupID == 0u) {
    float total = 0.0;
    for (uint s = gl_SubgroupInvocationID; s < gl_NumSubgroups; s += gl_SubgroupSize) {
      total += subgroup_sums[s];
    }
    total = subgroupAdd(total);
    if (subgroupElect()) partial[group] = total;
  }
}
