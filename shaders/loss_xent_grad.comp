#version 450
// Backward of loss_xent.comp: dx[r, j] = g[0] / rows · (softmax(x[r])_j - [j == label[r]]).
#extension GL_KHR_shader_subgroup_basic : require
#extension GL_KHR_shader_subgroup_arithmetic : require
#include "common.glsl"
layout(local_size_x = 256) in;
layout(binding = 0) uniform samplerBuffer x;
layout(binding = 1) uniform isamplerBuffer label;
layout(binding = 2) uniform samplerBuffer g;
layout(std430, binding = 3) writeonly buffer Dx { float dx[]; };
layout(push_constant) uniform Push {
  uint rows;
  uint k;
  float inv_rows;
} pc;

void main() {
  const uint row = linear_group() * gl_NumSubgroups + gl_SubgroupID;
  if (row >= pc.rows) return;
  const uint lane = gl_SubgroupInvocationID, sg = gl_SubgroupSize, base = row * pc.k;
  float m = uintBitsToFloat(0xff800000u);
  for (uint j = lane; j < pc.k; j += sg) m = max(m, texelFetch(x, int(base + j)).r);
  m = subgroupMax(m);
  float s = 0.0;
  for (uint j = lane; j < pc.k; j += sg) s += exp(texelFetch(x, int(base + j)).r - m);
  s = subgroupAdd(s);
  const float scale = texelFetch(g, 0).r * pc.inv_rows;
  const float inv = 1.0 / s;
  const int c = texelFetch(label, int(row)).r;
  for (uint j = lane; j < pc.k; j += sg) {
    const float p = exp(texelFetch(x, int(base + j)).r - m) * inv;
    dx[base + j] = scale * (p - (int(j) == c ? 1.0 : 0.0));
  }
}
