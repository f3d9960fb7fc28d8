#version 450
// Backward of softmax.comp from the saved output y: one subgroup per row.
//   softmax:     dx = y ⊙ (dy - Σ dy ⊙ y)
//   log-softmax: dx = dy - exp(y) Σ dy
#extension GL_KHR_shader_subgroup_basic : require
#extension GL_KHR_shader_subgroup_arithmetic : require
#include "common.glsl"
layout(local_size_x = 256) in;
layout(constant_id = 0) const bool LOG = false;
layout(binding = 0) uniform samplerBuffer y;
layout(binding = 1) uniform samplerBuffer dy;
layout(std430, binding = 2) writeonly buffer Dx { float dx[]; };
layout(push_constant) uniform Push {
  uint rows;
  uint k;
} pc;

void main() {
  const uint row = linear_group() * gl_NumSubgroups + gl_SubgroupID;
  if (row >= pc.rows) return;
  const uint lane = gl_SubgroupInvocationID, sg = gl_SubgroupSize, base = row * pc.k;
  float t = 0.0;
  for (uint j = lane; j < pc.k; j += sg) {
    const float g = texelFetch(dy, int(base + j)).r;
    t += LOG ? g : g * texelFetch(y, int(base + j)).r;
  }
  t = subgroupAdd(t);
  for (uint j = lane; j < pc.k; j += sg) {
    const float g = texelFetch(dy, int(base + j)).r, v = texelFetch(y, int(base + j)).r;
    dx[base + j] = LOG ? g - exp(v) * t : v * (g - t);
  }
}
