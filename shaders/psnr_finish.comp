#version 450
// Per-image result from the chunk sums of psnr_partial: one workgroup per
// image adds its `chunks` partial sums (fixed order, deterministic), then
//   MODE 0 (SSIM):  result = total / denominator (the mean of the map);
//   MODE 1 (PSNR):  mse = total / denominator, result = 10 log10(L^2 / mse),
//                   +inf when mse = 0, NaN when mse is NaN.
#extension GL_KHR_shader_subgroup_basic : require
#extension GL_KHR_shader_subgroup_arithmetic : require
#include "common.glsl"
layout(local_size_x = 256) in;
layout(constant_id = 0) const uint MODE = 0u;
layout(binding = 0) uniform samplerBuffer partial;
layout(std430, binding = 1) writeonly buffer Out { float result[]; };
layout(push_constant) uniform Push { uint images; uint chunks; float denominator; float range_sq; } pc;

shared float subgroup_sums[256];

void main() {
  const uint image = linear_group();
  if (image >= pc.images) return;  // uniform per workgroup
  float acc = 0.0;
  for (uint i = gl_LocalInvocationID.x; i < pc.chunks; i += 256u) {
    acc += texelFetch(partial, int(image * pc.chunks + i)).r;
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
    if (subgroupElect()) {
      const float mean = total / pc.denominator;
      if (MODE == 0u) {
        result[image] = mean;
      } else {
        // 10 log10(v) = 10 log10(2) log2(v)
        result[image] = mean > 0.0 ? 3.0102999566398120 * log2(pc.range_sq / mean)
                                   : (mean == 0.0 ? uintBitsToFloat(0x7f800000u) : mean);
      }
    }
  }
}
