#version 450
// dst[i] = value, as vec4 stores (4 per invocation, strided by the group
// size); the last n % 4 floats through a scalar alias of the binding.
#include "common.glsl"
layout(local_size_x = 256) in;
layout(std430, binding = 0) writeonly buffer Dst4 { vec4 dst4[]; };
layout(std430, binding = 0) writeonly buffer Dst1 { float dst1[]; };
layout(push_constant) uniform Push { uint n; float value; } pc;

void main() {
  const uint n4 = pc.n / 4u;
  const uint base = linear_group() * 1024u + gl_LocalInvocationID.x;
  [[unroll]] for (uint k = 0u; k < 4u; ++k) {
    const uint i = base + k * 256u;
    if (i < n4) dst4[i] = vec4(pc.value);
  }
  if (base == 0u) {
    for (uint i = n4 * 4u; i < pc.n; ++i) dst1[i] = pc.value;
  }
}
