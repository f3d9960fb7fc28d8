#version 450
// y = x * scale[c] (+ bias[c] when HAS_BIAS) on NCHW; with HAS_BIAS = 0 it is
// the backward dx = dy * scale[c]. Grid: x = chunks of one plane, y =
// channel, z = image, so the channel is uniform per workgroup (no
// per-element integer division: it is scalarized and slow on llvmpipe).
// VEC4 = 1 (H*W divisible by 4): x through an RGBA32F view and vec4 stores,
// 4 vec4 per invocation; else 4 floats per invocation.
#include "common.glsl"
layout(local_size_x = 256) in;
layout(constant_id = 0) const uint HAS_BIAS = 1u;
layout(constant_id = 1) const uint VEC4 = 0u;
layout(binding = 0) uniform samplerBuffer x;
layout(binding = 1) uniform samplerBuffer scale;
layout(binding = 2) uniform samplerBuffer bias;
layout(std430, binding = 3) writeonly buffer Y1 { float y1[]; };
layout(std430, binding = 3) writeonly buffer Y4 { vec4 y4[]; };
layout(push_constant) uniform Push { uint hw; uint channels; } pc;

void main() {
  const int c = int(gl_WorkGroupID.y);
  const uint plane = gl_WorkGroupID.z * pc.channels + uint(c);
  const float s = texelFetch(scale, c).r;
  const float b = HAS_BIAS != 0u ? texelFetch(bias, c).r : 0.0;
  const uint first = gl_WorkGroupID.x * 1024u + gl_LocalInvocationID.x;
  if (VEC4 != 0u) {
    const uint n4 = pc.hw / 4u, base = plane * n4;
    [[unroll]] for (uint k = 0u; k < 4u; ++k) {
      const uint i = first + k * 256u;
      if (i < n4) y4[base + i] = fma(texelFetch(x, int(base + i)), vec4(s), vec4(b));
    }
  } else {
    const uint base = plane * pc.hw;
    [[unroll]] for (uint k = 0u; k < 4u; ++k) {
      const uint i = first + k * 256u;
      if (i < pc.hw) y1[base + i] = fma(texelFetch(x, int(base + i)).r, s, b);
    }
  }
}
