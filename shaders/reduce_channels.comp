#version 450
// Per-channel sums over [N, C, spatial...]: out[c] = Σ_{n,s} term(a, b) with
// term = a (MODE 0), a·b (MODE 1) or a·min(b, 0) (MODE 2, the PReLU slope
// gradient). One subgroup per channel, lanes striding over the elements in a
// fixed order, then subgroupAdd: deterministic per device. Used for bias,
// scale and slope gradients and the column sums of linear layers (spatial 1).
#extension GL_KHR_shader_subgroup_basic : require
#extension GL_KHR_shader_subgroup_arithmetic : require
#include "common.glsl"
layout(local_size_x = 256) in;
layout(constant_id = 0) const uint MODE = 0u;
layout(binding = 0) uniform samplerBuffer a;  // usually dy
layout(binding = 1) uniform samplerBuffer b;  // x (MODE 1, 2)
layout(std430, binding = 2) writeonly buffer Out { float o[]; };
layout(push_constant) uniform Push {
  uint batch;
  uint channels;
  uint hw;
} pc;

float term(uint i) {
  const float x = texelFetch(a, int(i)).r;
  if (MODE == 0u) return x;
  const float y = texelFetch(b, int(i)).r;
  return MODE == 1u ? x * y : x * min(y, 0.0);
}

void main() {
  const uint c = linear_group() * gl_NumSubgroups + gl_SubgroupID;
  if (c >= pc.channels) return;
  const uint lane = gl_SubgroupInvocationID;
  float acc = 0.0;
  if (pc.hw >= gl_SubgroupSize) {
    for (uint n = 0u; n < pc.batch; ++n) {
      const uint plane = (n * pc.channels + c) * pc.hw;
      for (uint s = lane; s < pc.hw; s += gl_SubgroupSize) acc += term(plane + s);
    }
  } else {
    const uint total = pc.batch * pc.hw;
    for (uint j = lane; j < total; j += gl_SubgroupSize) {
      const uint n = j / pc.hw;
      acc += term((n * pc.channels + c) * pc.hw + (j - n * pc.hw));
    }
  }
  acc = subgroupAdd(acc);
  if (subgroupElect()) o[c] = acc;
}
