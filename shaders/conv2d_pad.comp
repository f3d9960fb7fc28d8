#version 450
// Zero-padded copy of x [n·cin planes of h × w] into xp [n·cin planes of
// hp × wp], x placed at (pt, pl). Lets the blocked and depthwise kernels read
// without bounds checks. 3-D grid, no integer division (scalarized and slow on
// llvmpipe): x = 4 output columns (one vec4 store; wp % 4 == 0), y = output
// row, z = plane, looping when the planes outnumber the z groups.
#include "common.glsl"
#include "conv2d_common.glsl"
layout(local_size_x = 16, local_size_y = 4) in;
layout(binding = 0) uniform samplerBuffer x;
layout(std430, binding = 1) writeonly buffer XP { vec4 xp[]; };

void main() {
  const uint q = gl_GlobalInvocationID.x;  // vec4 column
  const uint py = gl_GlobalInvocationID.y;
  const uint wq = pc.wp / 4u;
  if (q >= wq || py >= pc.hp) return;
  const uint planes = pc.n * pc.cin;
  const int sy = int(py) - pc.pt;
  const bool row_in = sy >= 0 && sy < int(pc.h);
  const int sx0 = int(q * 4u) - pc.pl;
  for (uint plane = gl_WorkGroupID.z; plane < planes; plane += gl_NumWorkGroups.z) {
    vec4 v = vec4(0.0);
    if (row_in) {
      const int src = int((plane * pc.h + uint(sy)) * pc.w);
      [[unroll]] for (int k = 0; k < 4; ++k) {
        const int sx = sx0 + k;
        if (sx >= 0 && sx < int(pc.w)) v[k] = texelFetch(x, src + sx).r;
      }
    }
    xp[(plane * pc.hp + py) * wq + q] = v;
  }
}
