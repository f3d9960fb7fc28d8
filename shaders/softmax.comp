#version 450
// Softmax (LOG false) or log-softmax (LOG true) over the last axis, numerically
// stable: y = exp(x - max) / Σ exp(x - max), log y = x - max - log Σ exp(x - max).
// One subgroup per row, three passes over the row (max, sum, write).
#extension GL_KHR_shader_subgroup_basic : require
#extension GL_KHR_shader_subgroup_arithmetic : require
#include "common.glsl"
layout(local_size_x = 256) in;
layout(constant_id = 0) const bool LOG = false;
layout(binding = 0) uniform samplerBuffer x;
layout(std430, binding = 1) writeonly buffer Y { float y[]; };
layout(push_constant) uniform Push {
  uint rows;
  uint k;
} pc;

void main() {
  const uint row = linear_group() * gl_NumSubgroups + gl_SubgroupID;
  if (row >= pc.rows) return;
  const uint lane = gl_SubgroupInvocationID, sg = gl_SubgroupSize, base = row * pc.k;
  float m = uintBitsToFloat(0xff800000u);  // -inf
  for (uint j = lane; j < pc.k; j += sg) m = max(m, texelFetch(x, int(base + j)).r);
  m = subgroupMax(m);
  float s = 0.0;
  for (uint j = lane; j < pc.k; j += sg) s += exp(texelFetch(x, int(base + j)).r - m);
  s = subgroupAdd(s);
  const float shift = LOG ? m + log(s) : m;
  const float inv = 1.0 / s;
  for (uint j = lane; j < pc.k; j += sg) {
    const float d = texelFetch(x, int(base + j)).r - shift;
    y[base + j] = LOG ? d : exp(d) * inv;
  }
}
