#version 450
// Backward of loss_cosine.comp given dy[rows], one subgroup per row. With
// ua = max(|a|, eps), ub = max(|b|, eps), c = a·b / (ua ub):
//   da = dy (b / (ua ub) - c a / ua²) (the second term only where |a| > eps), db likewise.
#extension GL_KHR_shader_subgroup_basic : require
#extension GL_KHR_shader_subgroup_arithmetic : require
#include "common.glsl"
layout(local_size_x = 256) in;
layout(binding = 0) uniform samplerBuffer a;
layout(binding = 1) uniform samplerBuffer b;
layout(binding = 2) uniform samplerBuffer dy;
layout(std430, binding = 3) writeonly buffer Da { float da[]; };
layout(std430, binding = 4) writeonly buffer Db { float db[]; };
layout(push_constant) uniform Push {
  uint rows;
  uint k;
  float eps;
} pc;

void main() {
  const uint row = linear_group() * gl_NumSubgroups + gl_SubgroupID;
  if (row >= pc.rows) return;
  const uint lane = gl_SubgroupInvocationID, sg = gl_SubgroupSize, base = row * pc.k;
  vec3 acc = vec3(0.0);
  for (uint j = lane; j < pc.k; j += sg) {
    const float u = texelFetch(a, int(base + j)).r, v = texelFetch(b, int(base + j)).r;
    acc += vec3(u * v, u * u, v * v);
  }
  acc = subgroupAdd(acc);
  const float na = sqrt(acc.y), nb = sqrt(acc.z);
  const float ua = max(na, pc.eps), ub = max(nb, pc.eps);
  const float g = texelFetch(dy, int(row)).r;
  const float inv_uab = 1.0 / (ua * ub);
  const float c = acc.x * inv_uab;
  const float ka = na > pc.eps ? c / (ua * ua) : 0.0;
  const float kb = nb > pc.eps ? c / (ub * ub) : 0.0;
  for (uint j = lane; j < pc.k; j += sg) {
    const float u = texelFetch(a, int(base + j)).r, v = texelFetch(b, int(base + j)).r;
    da[base + j] = g * (v * inv_uab - ka * u);
    db[base + j] = g * (u * inv_uab - kb * v);
  }
}
