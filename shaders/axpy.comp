#version 450
// y[i] += alpha * x[i], 4 elements per invocation; x read through a uniform
// texel buffer (vector gathers on lavapipe, see LAVAPIPE.md).
#include "common.glsl"
layout(local_size_x = 256) in;
layout(binding = 0) uniform samplerBuffer x;
layout(std430, binding = 1) buffer Y { float y[]; };
layout(push_constant) uniform Push { uint n; float alpha; } pc;

void main() {
  const uint base = linear_group() * 1024u + gl_LocalInvocationID.x;
  [[unroll]] for (uint k = 0u; k < 4u; ++k) {
    const uint i = base + k * 256u;
    if (i < pc.n) y[i] = fma(pc.alpha, texelFetch(x, int(i)).r, y[i]);
  }
}
