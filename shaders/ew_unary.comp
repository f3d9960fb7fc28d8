#version 450
// Unary elementwise ops (kernels/elementwise.hpp, kernels/activation.hpp),
// forward and backward; one pipeline per (OP, BACKWARD).
//   forward:  out[i] = f(a[i])
//   backward: out[i] = b[i] * f'(.) where a is the saved tensor: the input x
//             (scale_shift, log, relu, leaky_relu, prelu) or the output y
//             (exp, sigmoid, tanh).
// 4 elements per invocation, inputs through uniform texel buffers.
#include "common.glsl"
layout(local_size_x = 256) in;
layout(constant_id = 0) const uint OP = 0u;
layout(constant_id = 1) const bool BACKWARD = false;
layout(binding = 0) uniform samplerBuffer a;      // x, or the saved x / y
layout(binding = 1) uniform samplerBuffer b;      // dy (backward only)
layout(binding = 2) uniform samplerBuffer slope;  // PReLU slope per channel
layout(std430, binding = 3) writeonly buffer Out { float o[]; };
layout(push_constant) uniform Push {
  uint n;
  float p0;  // scale (scale_shift), slope (leaky_relu)
  float p1;  // shift (scale_shift)
  uint hw;        // PReLU: elements per channel plane
  uint channels;  // PReLU: channel count
} pc;

const uint kScaleShift = 0u, kExp = 1u, kLog = 2u, kRelu = 3u, kLeaky = 4u, kPrelu = 5u,
           kSigmoid = 6u, kTanh = 7u;

float prelu_slope(uint i) { return texelFetch(slope, int((i / pc.hw) % pc.channels)).r; }

float forward(float x, uint i) {
  if (OP == kScaleShift) return fma(pc.p0, x, pc.p1);
  if (OP == kExp) return exp(x);
  if (OP == kLog) return log(x);
  // `x < 0 ? .. : x` lets NaN through.
  if (OP == kRelu) return x < 0.0 ? 0.0 : x;
  if (OP == kLeaky) return x < 0.0 ? x * pc.p0 : x;
  if (OP == kPrelu) return x < 0.0 ? x * prelu_slope(i) : x;
  if (OP == kSigmoid) return 1.0 / (1.0 + exp(-x));
  // tanh from exp(-2|x|): no overflow for large |x|.
  const float t = exp(-2.0 * abs(x));
  return (x < 0.0 ? -1.0 : 1.0) * (1.0 - t) / (1.0 + t);
}

float backward(float s, float dy, uint i) {
  if (OP == kScaleShift) return dy * pc.p0;
  if (OP == kExp) return dy * s;
  if (OP == kLog) return dy / s;
  if (OP == kRelu) return s > 0.0 ? dy : 0.0;
  if (OP == kLeaky) return s > 0.0 ? dy : dy * pc.p0;
  if (OP == kPrelu) return s > 0.0 ? dy : dy * prelu_slope(i);
  if (OP == kSigmoid) return dy * s * (1.0 - s);
  return dy * (1.0 - s * s);
}

void main() {
  const uint base = linear_group() * 1024u + gl_LocalInvocationID.x;
  [[unroll]] for (uint k = 0u; k < 4u; ++k) {
    const uint i = base + k * 256u;
    if (i < pc.n) {
      const float s = texelFetch(a, int(i)).r;
      o[i] = BACKWARD ? backward(s, texelFetch(b, int(i)).r, i) : forward(s, i);
    }
  }
}
