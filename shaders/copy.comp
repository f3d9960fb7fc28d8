#version 450
// dst[i] = src[i]. The body moves vec4s read through an RGBA32F texel view
// (vector gathers on lavapipe; SSBO reads go lane by lane and were 4x
// slower), 4 per invocation strided by the group size; the last n % 4 floats
// come from an R32F view and go through a scalar alias of dst.
#include "common.glsl"
layout(local_size_x = 256) in;
layout(binding = 0) uniform samplerBuffer src4;
layout(binding = 1) uniform samplerBuffer src1;
layout(std430, binding = 2) writeonly buffer Dst4 { vec4 dst4[]; };
layout(std430, binding = 2) writeonly buffer Dst1 { float dst1[]; };
layout(push_constant) uniform Push { uint n; } pc;

void main() {
  const uint n4 = pc.n / 4u;
  const uint base = linear_group() * 1024u + gl_LocalInvocationID.x;
  [[unroll]] for (uint k = 0u; k < 4u; ++k) {
    const uint i = base + k * 256u;
    if (i < n4) dst4[i] = texelFetch(src4, int(i));
  }
  if (base == 0u) {
    for (uint i = n4 * 4u; i < pc.n; ++i) dst1[i] = texelFetch(src1, int(i)).r;
  }
}
