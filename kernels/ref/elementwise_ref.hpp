// Plain C++ references of kernels/elementwise and kernels/activation (tests only).
// Tensors are flat vectors; channel ops use [batch, channels, hw].
#pragma once

#include <cstdint>
#include <span>
#include <vector>

namespace vkjr2::ref {

enum class Unary { scale_shift, exp, log, relu, leaky_relu, sigmoid, tanh };

// y = f(x) with p0 = scale / slope, p1 = shift.
std::vector<float> unary(Unary op, std::span<const float> x, float p0 = 0.f, float p1 = 0.f);
// dx = dy · f'(saved), saved = x or y as documented in kernels/activation.hpp.
std::vector<float> unary_backward(Unary op, std::span<const float> saved, std::span<const float> dy,
                                  float p0 = 0.f);

// op: 0 add, 1 sub, 2 mul; b either the same size as a or one value per channel.
std::vector<float> binary(int op, std::span<const float> a, std::span<const float> b,
                          std::uint32_t channels = 0, std::uint32_t hw = 1);

std::vector<float> prelu(std::span<const float> x, std::span<const float> slope,
                         std::uint32_t channels, std::uint32_t hw);
void prelu_backward(std::span<const float> x, std::span<const float> slope,
                    std::span<const float> dy, std::uint32_t channels, std::uint32_t hw,
                    std::vector<float>& dx, std::vector<float>& dslope);

// NAFNet's SimpleGate on x [batch, 2·channels, hw] → [batch, channels, hw],
// and its backward (dx from dy [batch, channels, hw]).
std::vector<float> simple_gate(std::span<const float> x, std::uint32_t batch,
                               std::uint32_t channels, std::uint32_t hw);
std::vector<float> simple_gate_backward(std::span<const float> x, std::span<const float> dy,
                                        std::uint32_t batch, std::uint32_t channels,
                                        std::uint32_t hw);

// out[c] = Σ over [batch, ·, hw] of a (b empty) or a·b.
std::vector<float> channel_sum(std::span<const float> a, std::span<const float> b,
                               std::uint32_t channels, std::uint32_t hw);

}  // namespace vkjr2::ref
