// Plain C++ references of kernels/basic (tests and benchmarks only).
#pragma once

#include <span>

namespace vkjr2::ref {

void axpy(float alpha, std::span<const float> x, std::span<float> y);
double sum(std::span<const float> x);  // accumulated in double

}  // namespace vkjr2::ref
