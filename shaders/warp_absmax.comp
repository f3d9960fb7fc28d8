#version 450
// max |x| over x, as the bits of a non-negative float (their uint order is the
// float order, NaN above +inf), for the fixed-point scale of the d_img scatter
// in warp_sample_backward.comp. 16 elements per invocation, then one integer
// atomicMax (core Vulkan, order-independent). result[0] must start at 0.
#include "common.glsl"
layout(local_size_x = 256) in;
layout(binding = 0) uniform samplerBuffer x;
layout(std430, binding = 1) buffer Result { uint result[]; };
layout(push_constant) uniform Push { uint n; } pc;

void main() {
  const uint base = linear_group() * 4096u + gl_LocalInvocationID.x;
  uint m = 0u;
  [[unroll]] for (uint k = 0u; k < 16u; ++k) {
    const uint i = base + k * 256u;
    if (i < pc.n) m = max(m, floatBitsToUint(texelFetch(x, int(i)).r) & 0x7fffffffu);
  }
  if (m != 0u) atomicMax(result[0], m);
}
