#version 450
// First pass of the pointwise losses, mean over n elements of ρ(p - t):
// L1 |d| (OP 0), MSE d² (OP 1), Charbonnier sqrt(d² + eps²) (OP 2). Each
// workgroup adds 2048 terms (pre-scaled by 1/n) into partial[group] like
// reduce_sum.comp; the partials are then summed by kernels::sum.
#extension GL_KHR_shader_subgroup_basic : require
#extension GL_KHR_shader_subgroup_arithmetic : require
#include "common.glsl"
layout(local_size_x = 256) in;
layout(constant_id = 0) const uint OP = 0u;
layout(binding = 0) uniform samplerBuffer pred;
layout(binding = 1) uniform samplerBuffer target;
layout(std430, binding = 2) writeonly buffer Partial { float partial[]; };
layout(push_constant) uniform Push {
  uint n;
  float eps;
  float inv_n;
} pc;

shared float subgroup_sums[256];

float rho(float d) {
  if (OP == 0u) return abs(d);
  if (OP == 1u) return d * d;
  return sqrt(fma(d, d, pc.eps * pc.eps));
}

void main() {
  const uint group = linear_group();
  const uint base = group * 2048u + gl_LocalInvocationID.x;
  float acc = 0.0;
  [[unroll]] for (uint u = 0u; u < 8u; ++u) {
    const uint i = base + u * 256u;
    if (i < pc.n) acc += rho(texelFetch(pred, int(i)).r - texelFetch(target, int(i)).r);
  }
  acc = subgroupAdd(acc * pc.inv_n);
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
