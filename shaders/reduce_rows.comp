#version 450
// Row reductions over the last axis: out[r] = Σ_k x[r, k] (OP 0), · 1/K
// (OP 1, mean) or sqrt(Σ_k x²) (OP 2, L2 norm). One subgroup per row, lanes
// striding over the row in a fixed order (unrolled by 4), then subgroupAdd:
// deterministic per device.
#extension GL_KHR_shader_subgroup_basic : require
#extension GL_KHR_shader_subgroup_arithmetic : require
#include "common.glsl"
layout(local_size_x = 256) in;
layout(constant_id = 0) const uint OP = 0u;
layout(binding = 0) uniform samplerBuffer x;
layout(std430, binding = 1) writeonly buffer Out { float o[]; };
layout(push_constant) uniform Push {
  uint rows;
  uint k;
} pc;

float term(uint i) {
  const float v = texelFetch(x, int(i)).r;
  return OP == 2u ? v * v : v;
}

void main() {
  const uint row = linear_group() * gl_NumSubgroups + gl_SubgroupID;
  if (row >= pc.rows) return;
  const uint lane = gl_SubgroupInvocationID, sg = gl_SubgroupSize;
  const uint base = row * pc.k;
  vec4 acc = vec4(0.0);
  uint j = lane;
  for (; j + 3u * sg < pc.k; j += 4u * sg) {
    acc += vec4(term(base + j), term(base + j + sg), term(base + j + 2u * sg),
                term(base + j + 3u * sg));
  }
  for (; j < pc.k; j += sg) acc.x += term(base + j);
  float s = subgroupAdd((acc.x + acc.y) + (acc.z + acc.w));
  if (OP == 1u) s /= float(pc.k);
  if (OP == 2u) s = sqrt(s);
  if (subgroupElect()) o[row] = s;
}
