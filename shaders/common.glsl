// Shared helpers for vkjr2 compute shaders.
#ifndef VKJR2_COMMON_GLSL
#define VKJR2_COMMON_GLSL

#extension GL_EXT_control_flow_attributes : enable

// Linear workgroup index of a 1-D grid folded into (x, y) by groups_1d().
uint linear_group() { return gl_WorkGroupID.y * gl_NumWorkGroups.x + gl_WorkGroupID.x; }

// n / d for n < 2^31 by multiply-high (Granlund & Montgomery 1994):
// magic.x = ceil(2^(31 + l) / d), magic.y = l = ceil(log2 d); integer
// division is scalarized and slow on llvmpipe.
uint fast_div(uint n, uvec2 magic) {
  if (magic.y == 0u) return n;
  uint hi, lo;
  umulExtended(n, magic.x, hi, lo);
  return hi >> (magic.y - 1u);
}

#endif
