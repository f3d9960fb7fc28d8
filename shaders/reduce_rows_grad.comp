#version 450
// Backward of the row reductions of reduce_rows.comp, elementwise over x:
// dx[r, k] = dy[r] (OP 0), dy[r] / K (OP 1), dy[r] · x[r, k] / y[r] (OP 2,
// 0 where y[r] = 0). With one row this is the backward of a full reduction.
#include "common.glsl"
layout(local_size_x = 256) in;
layout(constant_id = 0) const uint OP = 0u;
layout(binding = 0) uniform samplerBuffer dy;  // per row
layout(binding = 1) uniform samplerBuffer x;   // OP 2
layout(binding = 2) uniform samplerBuffer y;   // OP 2: the row norms
layout(std430, binding = 3) writeonly buffer Dx { float dx[]; };
layout(push_constant) uniform Push {
  uint n;
  uint k;
} pc;

void main() {
  const uint base = linear_group() * 1024u + gl_LocalInvocationID.x;
  [[unroll]] for (uint u = 0u; u < 4u; ++u) {
    const uint i = base + u * 256u;
    if (i < pc.n) {
      const int row = int(i / pc.k);
      const float g = texelFetch(dy, row).r;
      if (OP == 0u) {
        dx[i] = g;
      } else if (OP == 1u) {
        dx[i] = g / float(pc.k);
      } else {
        const float norm = texelFetch(y, row).r;
        dx[i] = norm > 0.0 ? g * texelFetch(x, int(i)).r / norm : 0.0;
      }
    }
  }
}
