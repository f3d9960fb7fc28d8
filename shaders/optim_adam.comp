#version 450
// Adam / AdamW step, in place (Kingma & Ba 2015, Alg. 1; AdamW: Loshchilov &
// Hutter 2019, decoupled weight decay). With bias corrections bc1 = 1 - β1^t,
// bc2 = 1 - β2^t of step t (from the host, in double):
//   Adam:  g' = g + wd·p
//   AdamW: p *= 1 - lr·wd, g' = g
//   m = β1 m + (1-β1) g';  v = β2 v + (1-β2) g'²
//   p -= (lr / bc1) · m / (sqrt(v) / sqrt(bc2) + eps)
#include "common.glsl"
layout(local_size_x = 256) in;
layout(binding = 0) uniform samplerBuffer grad;
layout(std430, binding = 1) buffer Param { float p[]; };
layout(std430, binding = 2) buffer M { float m[]; };
layout(std430, binding = 3) buffer V { float v[]; };
layout(push_constant) uniform Push {
  uint n;
  uint step;  // t ≥ 1 (the corrections below are computed from it)
  uint decoupled;
  float lr;
  float beta1;
  float beta2;
  float eps;
  float weight_decay;
  float step_size;      // lr / bc1
  float bc2_sqrt;       // sqrt(bc2)
} pc;

void main() {
  const uint base = linear_group() * 1024u + gl_LocalInvocationID.x;
  [[unroll]] for (uint u = 0u; u < 4u; ++u) {
    const uint i = base + u * 256u;
    if (i < pc.n) {
      float w = p[i];
      float g = texelFetch(grad, int(i)).r;
      if (pc.decoupled != 0u) {
        w *= 1.0 - pc.lr * pc.weight_decay;
      } else {
        g += pc.weight_decay * w;
      }
      const float mi = pc.beta1 * m[i] + (1.0 - pc.beta1) * g;
      const float vi = pc.beta2 * v[i] + (1.0 - pc.beta2) * g * g;
      m[i] = mi;
      v[i] = vi;
      p[i] = w - pc.step_size * (mi / (sqrt(vi) / pc.bc2_sqrt + pc.eps));
    }
  }
}
