#version 450
// Benchmark kernel: peak fp32 FMA throughput. 16 independent vec4 chains per
// invocation (enough to hide FMA latency), inner loop unrolled by 4.
#include "common.glsl"
layout(local_size_x = 64) in;
layout(std430, binding = 0) writeonly buffer Out { vec4 result[]; };
layout(push_constant) uniform Push { uint iterations; float a; float b; } pc;

void main() {
  vec4 acc[16];
  [[unroll]] for (int j = 0; j < 16; ++j) acc[j] = vec4(float(gl_GlobalInvocationID.x + j));
  const vec4 a = vec4(pc.a), b = vec4(pc.b);
  for (uint i = 0u; i < pc.iterations; ++i) {
    [[unroll]] for (int u = 0; u < 4; ++u) {
      [[unroll]] for (int j = 0; j < 16; ++j) acc[j] = fma(acc[j], a, b);
    }
  }
  vec4 s = vec4(0.0);
  [[unroll]] for (int j = 0; j < 16; ++j) s += acc[j];
  result[linear_group() * 64u + gl_LocalInvocationID.x] = s;
}
