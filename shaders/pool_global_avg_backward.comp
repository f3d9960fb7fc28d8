#version 450
// Global average pool backward: dx[i] = dy[i / HW] / HW, 4 elements per
// invocation.
#include "common.glsl"
layout(local_size_x = 256) in;
layout(binding = 0) uniform samplerBuffer dy;
layout(std430, binding = 1) writeonly buffer DX { float dx[]; };
layout(push_constant) uniform Push { uint n; uint hw; } pc;

void main() {
  const uint base = linear_group() * 1024u + gl_LocalInvocationID.x;
  const float inv = 1.0 / float(pc.hw);
  [[unroll]] for (uint k = 0u; k < 4u; ++k) {
    const uint i = base + k * 256u;
    if (i < pc.n) dx[i] = texelFetch(dy, int(i / pc.hw)).r * inv;
  }
}
