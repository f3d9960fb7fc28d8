#version 450
// Counter-based Gaussian noise, 4 values per invocation (kernels/random.hpp).
// Element i takes normals from the hash of (i / 4, stream id, seed): the
// pcg4d hash (Jarzynski & Olano 2020) gives four 32-bit words, Box–Muller
// turns them into four normals. No state: any element can be regenerated.
// mode 0: out = mean + stddev · n
// mode 1: x = rho · x + sqrt(1 − rho²) · n                (AR(1) update, in place)
// mode 2: out = x + sqrt(max(x, 0) · shot + read²) · n     (Poisson–Gaussian sensor)
#include "common.glsl"
#include "random.glsl"
layout(local_size_x = 256) in;
layout(std430, binding = 0) readonly buffer X { float x[]; };
layout(std430, binding = 1) buffer Y { float y[]; };
layout(push_constant) uniform Push {
  uint n;
  uint stream_id;
  uvec2 seed;
  uint mode;
  float a;  // mode 0: mean;   mode 1: rho;             mode 2: shot (variance per unit signal)
  float b;  // mode 0: stddev; mode 1: sqrt(1 − rho²);  mode 2: read² (variance)
} pc;

void main() {
  const uint g = linear_group() * 256u + gl_LocalInvocationID.x;
  const uint base = g * 4u;
  if (base >= pc.n) return;
  const vec4 nrm = gaussian4(uvec4(g, pc.stream_id, pc.seed.x, pc.seed.y));
  [[unroll]] for (uint k = 0u; k < 4u; ++k) {
    const uint i = base + k;
    if (i >= pc.n) break;
    if (pc.mode == 0u) {
      y[i] = fma(pc.b, nrm[k], pc.a);
    } else if (pc.mode == 1u) {
      y[i] = fma(pc.a, y[i], pc.b * nrm[k]);
    } else {
      const float v = x[i];
      y[i] = fma(sqrt(fma(max(v, 0.0), pc.a, pc.b)), nrm[k], v);
    }
  }
}
