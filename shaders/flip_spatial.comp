#version 450
// y[n, c, i, j] = x[n, c, H − 1 − i, W − 1 − j]: both spatial axes reversed
// (a convolution kernel rotated by 180°; its own inverse and backward).
// Grid: x = 256-element chunks of one plane (folded into x, y by groups_1d
// when large), z = plane, so the only division is by the plane's width.
#include "common.glsl"
layout(local_size_x = 256) in;
layout(binding = 0) uniform samplerBuffer x;
layout(std430, binding = 1) writeonly buffer Y { float y[]; };
layout(push_constant) uniform Push { uint h; uint w; } pc;

void main() {
  const uint plane_size = pc.h * pc.w;
  const uint i = linear_group() * 256u + gl_LocalInvocationID.x;
  if (i >= plane_size) return;
  const uint base = gl_WorkGroupID.z * plane_size;
  y[base + i] = texelFetch(x, int(base + plane_size - 1u - i)).r;
}
