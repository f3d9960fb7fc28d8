#version 450
// Zero-padded copy of x [n·cin planes of h × w] into xp [n·cin planes of
// hp × wp], x placed at (pt, pl); 4 elements per invocation. Lets the blocked
// and depthwise kernels read without bounds checks.
#include "common.glsl"
#include "conv2d_common.glsl"
layout(local_size_x = 256) in;
layout(binding = 0) uniform samplerBuffer x;
layout(std430, binding = 1) writeonly buffer XP { float xp[]; };

void main() {
  const uint total = pc.n * pc.cin * pc.hp * pc.wp;
  const uint base = linear_group() * 1024u + gl_LocalInvocationID.x;
  [[unroll]] for (uint k = 0u; k < 4u; ++k) {
    const uint i = base + k * 256u;
    if (i >= total) return;
    const uint px = i % pc.wp;
    const uint t = i / pc.wp;
    const uint py = t % pc.hp;
    const uint plane = t / pc.hp;
    const int sy = int(py) - pc.pt;
    const int sx = int(px) - pc.pl;
    float v = 0.0;
    if (sy >= 0 && sy < int(pc.h) && sx >= 0 && sx < int(pc.w)) {
      v = texelFetch(x, int((plane * pc.h + uint(sy)) * pc.w + uint(sx))).r;
    }
    xp[i] = v;
  }
}
