#version 450
// Maximum and its index per row of K: one subgroup per row. Ties go to the
// smallest index; NaN counts as the maximum (the first NaN wins). The last
// row may be short (n bounds the flat index), so a flat array can be cut
// into rows and reduced in passes: with INDEX_IN the winner's index is
// looked up in idx_in (the previous pass's indices), else it is the index
// within the row (global == 0) or the flat index (global == 1).
#extension GL_KHR_shader_subgroup_basic : require
#extension GL_KHR_shader_subgroup_arithmetic : require
#include "common.glsl"
layout(local_size_x = 256) in;
layout(constant_id = 0) const bool INDEX_IN = false;
layout(binding = 0) uniform samplerBuffer x;
layout(binding = 1) uniform isamplerBuffer idx_in;
layout(std430, binding = 2) writeonly buffer Value { float value[]; };
layout(std430, binding = 3) writeonly buffer Index { int index[]; };
layout(push_constant) uniform Push {
  uint rows;
  uint k;
  uint n;
  uint global_index;
} pc;

const uint kNone = 0xffffffffu;

void main() {
  const uint row = linear_group() * gl_NumSubgroups + gl_SubgroupID;
  if (row >= pc.rows) return;
  const uint lane = gl_SubgroupInvocationID;
  const uint base = row * pc.k;
  const uint len = min(pc.k, pc.n - base);
  float best = 0.0;
  uint best_j = kNone, nan_j = kNone;
  for (uint j = lane; j < len; j += gl_SubgroupSize) {
    const float v = texelFetch(x, int(base + j)).r;
    if (isnan(v)) {
      nan_j = min(nan_j, j);
    } else if (best_j == kNone || v > best) {
      best = v;
      best_j = j;
    }
  }
  // Lanes without a candidate must not win: give them -inf and no index.
  const float lane_best = best_j == kNone ? uintBitsToFloat(0xff800000u) : best;
  const float m = subgroupMax(lane_best);
  uint j = subgroupMin(best_j != kNone && lane_best == m ? best_j : kNone);
  float v = m;
  nan_j = subgroupMin(nan_j);
  if (nan_j != kNone) {
    j = nan_j;
    v = uintBitsToFloat(0x7fc00000u);
  }
  if (subgroupElect()) {
    value[row] = v;
    int id = int(j);
    if (INDEX_IN) {
      id = texelFetch(idx_in, int(base + j)).r;
    } else if (pc.global_index != 0u) {
      id = int(base + j);
    }
    index[row] = id;
  }
}
