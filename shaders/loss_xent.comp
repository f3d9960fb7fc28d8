#version 450
// Cross-entropy over logits [rows, k] with i32 labels, one subgroup per row:
// loss[r] = (logsumexp(x[r]) - x[r, label[r]]) / rows, summed afterwards by
// kernels::sum into the mean. A label outside [0, k) gives NaN.
#extension GL_KHR_shader_subgroup_basic : require
#extension GL_KHR_shader_subgroup_arithmetic : require
#include "common.glsl"
layout(local_size_x = 256) in;
layout(binding = 0) uniform samplerBuffer x;
layout(binding = 1) uniform isamplerBuffer label;
layout(std430, binding = 2) writeonly buffer Loss { float loss[]; };
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
  if (subgroupElect()) {
    const int c = texelFetch(label, int(row)).r;
    const bool ok = c >= 0 && uint(c) < pc.k;
    const float picked = ok ? texelFetch(x, int(base) + c).r : 0.0;
    loss[row] = ok ? (m + log(s) - picked) * pc.inv_rows : uintBitsToFloat(0x7fc00000u);
  }
}
