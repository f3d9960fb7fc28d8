#version 450
// dscale[c] = sum over n, pixels of dy * x; dbias[c] = sum of dy. One
// workgroup per channel: strided partial sums, subgroup adds, one shared
// step across subgroups (fixed order: deterministic).
#extension GL_KHR_shader_subgroup_basic : require
#extension GL_KHR_shader_subgroup_arithmetic : require
#include "common.glsl"
layout(local_size_x = 256) in;
layout(binding = 0) uniform samplerBuffer x;
layout(binding = 1) uniform samplerBuffer dy;
layout(std430, binding = 2) writeonly buffer DS { float dscale[]; };
layout(std430, binding = 3) writeonly buffer DB { float dbias[]; };
layout(push_constant) uniform Push { uint batch; uint hw; uint channels; } pc;

shared vec2 subgroup_sums[256];

void main() {
  const uint c = linear_group();
  if (c >= pc.channels) return;  // uniform per workgroup
  vec2 acc0 = vec2(0.0), acc1 = vec2(0.0);
  for (uint n = 0u; n < pc.batch; ++n) {
    const uint base = (n * pc.channels + c) * pc.hw;
    uint i = gl_LocalInvocationID.x;
    for (; i + 256u < pc.hw; i += 512u) {
      const float g0 = texelFetch(dy, int(base + i)).r;
      const float g1 = texelFetch(dy, int(base + i + 256u)).r;
      acc0 += vec2(g0 * texelFetch(x, int(base + i)).r, g0);
      acc1 += vec2(g1 * texelFetch(x, int(base + i + 256u)).r, g1);
    }
    if (i < pc.hw) {
      const float g = texelFetch(dy, int(base + i)).r;
      acc0 += vec2(g * texelFetch(x, int(base + i)).r, g);
    }
  }
  const vec2 acc = subgroupAdd(acc0 + acc1);
  if (subgroupElect()) subgroup_sums[gl_SubgroupID] = acc;
  barrier();
  if (gl_SubgroupID == 0u) {
    vec2 total = vec2(0.0);
    for (uint s = gl_SubgroupInvocationID; s < gl_NumSubgroups; s += gl_SubgroupSize) {
      total += subgroup_sums[s];
    }
    total = subgroupAdd(total);
    if (subgroupElect()) {
      dscale[c] = total.x;
      dbias[c] = total.y;
    }
  }
}
