#version 450
// grid[n, h, w] = theta[n] · (x_w, y_h, 1) (PyTorch affine_grid, 2-D), with
// base coordinates x_w = align ? -1 + 2w/(W-1) : (2w+1)/W - 1 (0 when W = 1).
// One invocation per output pixel.
#include "common.glsl"
layout(local_size_x = 256) in;
layout(binding = 0) uniform samplerBuffer theta;  // N×2×3, R32F
layout(std430, binding = 1) writeonly buffer Grid { vec2 grid[]; };
layout(push_constant) uniform Push {
  uint n_batch;
  uint h;
  uint w;
  uint align_corners;
} pc;

float base_coord(uint i, uint size) {
  if (size <= 1u) return 0.0;
  if (pc.align_corners != 0u) return -1.0 + 2.0 * float(i) / float(size - 1u);
  return (2.0 * float(i) + 1.0) / float(size) - 1.0;
}

void main() {
  const uint plane = pc.h * pc.w;
  const uint gid = linear_group() * 256u + gl_LocalInvocationID.x;
  if (gid >= pc.n_batch * plane) return;
  const uint n = gid / plane, p = gid % plane;
  const float x = base_coord(p % pc.w, pc.w), y = base_coord(p / pc.w, pc.h);
  const int t = int(6u * n);
  vec2 g;
  g.x = texelFetch(theta, t + 0).r * x + texelFetch(theta, t + 1).r * y + texelFetch(theta, t + 2).r;
  g.y = texelFetch(theta, t + 3).r * x + texelFetch(theta, t + 4).r * y + texelFetch(theta, t + 5).r;
  grid[gid] = g;
}
