#version 450
// out = a OP b (add, sub, mul), elementwise on equal shapes or with b a
// per-channel vector broadcast over [N, C, spatial...] (CHANNEL). 4 elements
// per invocation, inputs through uniform texel buffers.
#include "common.glsl"
layout(local_size_x = 256) in;
layout(constant_id = 0) const uint OP = 0u;  // 0 add, 1 sub, 2 mul
layout(constant_id = 1) const bool CHANNEL = false;
layout(binding = 0) uniform samplerBuffer a;
layout(binding = 1) uniform samplerBuffer b;
layout(std430, binding = 2) writeonly buffer Out { float o[]; };
layout(push_constant) uniform Push {
  uint n;
  uint hw;        // CHANNEL: elements per channel plane
  uint channels;  // CHANNEL: channel count
} pc;

void main() {
  const uint base = linear_group() * 1024u + gl_LocalInvocationID.x;
  [[unroll]] for (uint k = 0u; k < 4u; ++k) {
    const uint i = base + k * 256u;
    if (i < pc.n) {
      const float x = texelFetch(a, int(i)).r;
      const int j = CHANNEL ? int((i / pc.hw) % pc.channels) : int(i);
      const float v = texelFetch(b, j).r;
      o[i] = OP == 0u ? x + v : (OP == 1u ? x - v : x * v);
    }
  }
}
