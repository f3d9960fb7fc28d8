#version 450
// Cosine similarity per row of a, b [rows, k], one subgroup per row:
// y[r] = a·b / (max(|a|, eps) · max(|b|, eps)).
#extension GL_KHR_shader_subgroup_basic : require
#extension GL_KHR_shader_subgroup_arithmetic : require
#include "common.glsl"
layout(local_size_x = 256) in;
layout(binding = 0) uniform samplerBuffer a;
layout(binding = 1) uniform samplerBuffer b;
layout(std430, binding = 2) writeonly buffer Y { float y[]; };
layout(push_constant) uniform Push {
  uint rows;
  uint k;
  float eps;
} pc;

void main() {
  const uint row = linear_group() * gl_NumSubgroups + gl_SubgroupID;
  if (row >= pc.rows) return;
  const uint lane = gl_SubgroupInvocationID, sg = gl_SubgroupSize, base = row * pc.k;
  vec3 acc = vec3(0.0);  // a·b, |a|², |b|²
  for (uint j = lane; j < pc.k; j += sg) {
    const float u = texelFetch(a, int(base + j)).r, v = texelFetch(b, int(base + j)).r;
    acc += vec3(u * v, u * u, v * v);
  }
  acc = subgroupAdd(acc);
  if (subgroupElect()) y[row] = acc.x / (max(sqrt(acc.y), pc.eps) * max(sqrt(acc.z), pc.eps));
}
