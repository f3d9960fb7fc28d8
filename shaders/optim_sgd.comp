#version 450
// SGD with momentum, in place (PyTorch's form, dampening 0, no Nesterov):
//   g' = g + wd·p;  v = momentum·v + g';  p -= lr·v.  v must start at 0.
#include "common.glsl"
layout(local_size_x = 256) in;
layout(binding = 0) uniform samplerBuffer grad;
layout(std430, binding = 1) buffer Param { float p[]; };
layout(std430, binding = 2) buffer Velocity { float v[]; };
layout(push_constant) uniform Push {
  uint n;
  float lr;
  float momentum;
  float weight_decay;
} pc;

void main() {
  const uint base = linear_group() * 1024u + gl_LocalInvocationID.x;
  [[unroll]] for (uint u = 0u; u < 4u; ++u) {
    const uint i = base + u * 256u;
    if (i < pc.n) {
      const float w = p[i];
      const float g = texelFetch(grad, int(i)).r + pc.weight_decay * w;
      const float vel = pc.momentum * v[i] + g;
      v[i] = vel;
      p[i] = w - pc.lr * vel;
    }
  }
}
