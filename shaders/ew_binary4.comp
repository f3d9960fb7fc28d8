#version 450
// out = a OP b (add, sub, mul) on equal shapes whose element count is a
// multiple of 4: both inputs read as RGBA32F texels (one gather for four
// elements), output written as vec4, 4 vec4 per invocation. Bounds are
// checked only in the last workgroup. (ew_binary.comp: other counts and the
// per-channel broadcast.)
#include "common.glsl"
layout(local_size_x = 256) in;
layout(constant_id = 0) const uint OP = 0u;  // 0 add, 1 sub, 2 mul
layout(binding = 0) uniform samplerBuffer a;  // RGBA32F
layout(binding = 1) uniform samplerBuffer b;  // RGBA32F
layout(std430, binding = 2) writeonly buffer Out { vec4 o[]; };
layout(push_constant) uniform Push {
  uint n4;  // element count / 4
} pc;

vec4 apply(int i) {
  const vec4 x = texelFetch(a, i), v = texelFetch(b, i);
  return OP == 0u ? x + v : (OP == 1u ? x - v : x * v);
}

void main() {
  const uint group_start = linear_group() * 1024u;
  const uint base = group_start + gl_LocalInvocationID.x;
  if (group_start + 1024u <= pc.n4) {
    [[unroll]] for (uint k = 0u; k < 4u; ++k) {
      const uint i = base + k * 256u;
      o[i] = apply(int(i));
    }
  } else {
    [[unroll]] for (uint k = 0u; k < 4u; ++k) {
      const uint i = base + k * 256u;
      if (i < pc.n4) o[i] = apply(int(i));
    }
  }
}
