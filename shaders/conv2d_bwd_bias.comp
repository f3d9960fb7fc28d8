#version 450
// conv2d backward-bias: dbias[co] = Σ_{n, pixels} dy[n, co, :, :]; one
// workgroup per channel, subgroup adds then one shared-memory step.
#extension GL_KHR_shader_subgroup_basic : require
#extension GL_KHR_shader_subgroup_arithmetic : require
#include "common.glsl"
#include "conv2d_common.glsl"
layout(local_size_x = 64) in;
layout(binding = 0) uniform samplerBuffer dy_out;  // [n, cout, hout, wout]
layout(std430, binding = 1) writeonly buffer DB { float dbias[]; };

shared float subgroup_sums[64];

void main() {
  const uint co = linear_group();
  if (co >= pc.cout) return;  // whole workgroup: uniform
  const uint hw = pc.hout * pc.wout;
  float acc = 0.0;
  for (uint n = 0u; n < pc.n; ++n) {
    const uint base = (n * pc.cout + co) * hw;
    for (uint p = gl_LocalInvocationID.x; p < hw; p += 64u) {
      acc += texelFetch(dy_out, int(base + p)).r;
    }
  }
  acc = subgroupAdd(acc);
  if (subgroupElect()) subgroup_sums[gl_SubgroupID] = acc;
  barrier();
  if (gl_LocalInvocationID.x == 0u) {
    float total = 0.0;
    for (uint s = 0u; s < gl_NumSubgroups; ++s) total += subgroup_sums[s];
    dbias[co] = total;
  }
}
