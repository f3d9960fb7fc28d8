// Plain C++ references of kernels/loss (tests only), accumulated in double.
#pragma once

#include <cstddef>
#include <cstdint>
#include <span>
#include <vector>

namespace vkjr2::ref {

// kind: 0 L1, 1 MSE, 2 Charbonnier. Mean over elements; backward for g = 1.
double pointwise_loss(int kind, std::span<const float> pred, std::span<const float> target,
                      float eps);
std::vector<float> pointwise_loss_backward(int kind, std::span<const float> pred,
                                           std::span<const float> target, float eps, float g);

std::vector<float> cosine_similarity(std::span<const float> a, std::span<const float> b,
                                     std::size_t k, float eps);
void cosine_similarity_backward(std::span<const float> a, std::span<const float> b,
                                std::span<const float> dy, std::size_t k, float eps,
                                std::vector<float>& da, std::vector<float>& db);

double cross_entropy(std::span<const float> logits, std::span<const std::int32_t> labels,
                     std::size_t k);
std::vector<float> cross_entropy_backward(std::span<const float> logits,
                                          std::span<const std::int32_t> labels, std::size_t k,
                                          float g);

}  // namespace vkjr2::ref
