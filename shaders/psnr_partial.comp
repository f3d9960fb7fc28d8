#version 450
// Per-image partial sums for PSNR and SSIM: workgroup g sums a 4096-element
// chunk (image g / chunks, chunk g % chunks) of (a - b)^2 (SQUARED_DIFF = 1,
// PSNR) or of a (SQUARED_DIFF = 0, the SSIM map) into partial[g]. Several
// workgroups per image keep every core busy for a batch of one. Strided
// partial sums, subgroup adds, one shared step: fixed order, deterministic.
#extension GL_KHR_shader_subgroup_basic : require
#extension GL_KHR_shader_subgroup_arithmetic : require
#include "common.glsl"
layout(local_size_x = 256) in;
layout(constant_id = 0) const uint SQUARED_DIFF = 1u;
layout(binding = 0) uniform samplerBuffer a;
layout(binding = 1) uniform samplerBuffer b;
layout(std430, binding = 2) writeonly buffer Partial { float partial[]; };
layout(push_constant) uniform Push { uint groups; uint chunks; uint count; } pc;

shared float subgroup_sums[256];

float term(uint i) {
  const float x = texelFetch(a, int(i)).r;
  if (SQUARED_DIFF == 0u) return x;
  const float d = x - texelFetch(b, int(i)).r;
  return d * d;
}

void main() {
  const uint g = linear_group();
  if (g >= pc.groups) return;  // uniform per workgroup
  const uint image = g / pc.chunks, chunk = g % pc.chunks;
  const uint begin = chunk * 4096u;
  const uint end = min(begin + 4096u, pc.count);
  const uint base = image * pc.count;
  float acc[4] = float[4](0.0, 0.0, 0.0, 0.0);
  [[unroll]] for (uint k = 0u; k < 16u; ++k) {
    const uint i = begin + k * 256u + gl_LocalInvocationID.x;
    if (i < end) acc[k & 3u] += term(base + i);
  }
  const float sum = subgroupAdd((acc[0] + acc[1]) + (acc[2] + acc[3]));
  if (subgroupElect()) subgroup_sums[gl_SubgroupID] = sum;
  barrier();
  if (gl_SubgroupID == 0u) {
    float total = 0.0;
    for (uint s = gl_SubgroupInvocationID; s < gl_NumSubgroups; s += gl_SubgroupSize) {
      total += subgroup_sums[s];
    }
    total = subgroupAdd(total);
    if (subgroupElect()) partial[g] = total;
  }
}
