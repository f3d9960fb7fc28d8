#version 450
// dst[i] = src[i], 4 elements per invocation.
#include "common.glsl"
layout(local_size_x = 256) in;
layout(std430, binding = 0) readonly buffer Src { float src[]; };
layout(std430, binding = 1) writeonly buffer Dst { float dst[]; };
layout(push_constant) uniform Push { uint n; } pc;

void main() {
  const uint base = linear_group() * 1024u + gl_LocalInvocationID.x;
  [[unroll]] for (uint k = 0u; k < 4u; ++k) {
    const uint i = base + k * 256u;
    if (i < pc.n) dst[i] = src[i];
  }
}
