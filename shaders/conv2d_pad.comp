#version 450
// Zero-padded copy of x [n·cin planes of h × w] into xp [n·cin planes of
// hp × wp], x placed at (pt, pl). Lets the blocked and depthwise kernels read
// without bounds checks. 3-D grid, no integer division (scalarized and slow on
// llvmpipe): x = 4 output columns (one vec4 store; wp % 4 == 0), y = output
// row, z = plane, looping when the planes outnumber the z groups.
// VEC4 = 1 (w % 4 == 0, x 16-byte aligned): x read as RGBA32F quads, two
// per output quad, shifted by SHIFT = (−pl) mod 4 columns (constant
// swizzles); a row's quads are all inside it or all outside.
#include "common.glsl"
#include "conv2d_common.glsl"
layout(local_size_x = 16, local_size_y = 4) in;
layout(constant_id = 0) const uint VEC4 = 0u;
layout(constant_id = 1) const uint SHIFT = 0u;
layout(binding = 0) uniform samplerBuffer x;  // R32F; RGBA32F when VEC4
layout(std430, binding = 1) writeonly buffer XP { vec4 xp[]; };

// Columns SHIFT.. of a followed by b.
vec4 shifted(vec4 a, vec4 b) {
  if (SHIFT == 0u) return a;
  if (SHIFT == 1u) return vec4(a.yzw, b.x);
  if (SHIFT == 2u) return vec4(a.zw, b.xy);
  return vec4(a.w, b.xyz);
}

void main() {
  const uint q = gl_GlobalInvocationID.x;  // vec4 column
  const uint py = gl_GlobalInvocationID.y;
  const uint wq = pc.wp / 4u;
  if (q >= wq || py >= pc.hp) return;
  const uint planes = pc.n * pc.cin;
  const int sy = int(py) - pc.pt;
  const bool row_in = sy >= 0 && sy < int(pc.h);
  const int sx0 = int(q * 4u) - pc.pl;
  // VEC4: the quads holding columns sx0 .. sx0 + 3 (qa·4 = sx0 − SHIFT).
  const int qa = (sx0 - int(SHIFT)) / 4;  // exact: sx0 ≡ SHIFT (mod 4)
  const int wq_in = int(pc.w / 4u);
  const bool a_in = qa >= 0 && qa < wq_in, b_in = qa + 1 >= 0 && qa + 1 < wq_in;
  for (uint plane = gl_WorkGroupID.z; plane < planes; plane += gl_NumWorkGroups.z) {
    vec4 v = vec4(0.0);
    if (row_in) {
      const int src = int((plane * pc.h + uint(sy)) * pc.w);
      if (VEC4 != 0u) {
        const int src4 = src / 4;
        const vec4 a = a_in ? texelFetch(x, src4 + qa) : vec4(0.0);
        const vec4 b = SHIFT != 0u && b_in ? texelFetch(x, src4 + qa + 1) : vec4(0.0);
        v = shifted(a, b);
      } else {
        [[unroll]] for (int k = 0; k < 4; ++k) {
          const int sx = sx0 + k;
          if (sx >= 0 && sx < int(pc.w)) v[k] = texelFetch(x, src + sx).r;
        }
      }
    }
    xp[(plane * pc.hp + py) * wq + q] = v;
  }
}
