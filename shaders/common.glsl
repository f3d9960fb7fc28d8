// Shared helpers for vkjr2 compute shaders.
#ifndef VKJR2_COMMON_GLSL
#define VKJR2_COMMON_GLSL

#extension GL_EXT_control_flow_attributes : enable

// Linear workgroup index of a 1-D grid folded into (x, y) by groups_1d().
uint linear_group() { return gl_WorkGroupID.y * gl_NumWorkGroups.x + gl_WorkGroupID.x; }

#endif
