#version 450
// dst[i] = value. Each invocation writes 4 elements, strided by the group
// size so neighbouring invocations touch neighbouring words.
#include "common.glsl"
layout(local_size_x = 256) in;
layout(std430, binding = 0) writeonly buffer Dst { float dst[]; };
layout(push_constant) uniform Push { uint n; float value; } pc;

void main() {
  const uint base = linear_group() * 1024u + gl_LocalInvocationID.x;
  [[unroll]] for (uint k = 0u; k < 4u; ++k) {
    const uint i = base + k * 256u;
    if (i < pc.n) dst[i] = pc.value;
  }
}
