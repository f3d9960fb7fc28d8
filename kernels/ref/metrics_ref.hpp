// Plain C++ references of kernels/metrics (tests and benchmarks only).
#pragma once

#include <cstdint>
#include <span>
#include <vector>

namespace vkjr2::ref {

// Per image of [n, c, h, w]: 10·log10(L² / mse), +inf when mse = 0.
std::vector<double> psnr(std::span<const float> a, std::span<const float> b, std::int64_t n,
                         std::int64_t c, std::int64_t h, std::int64_t w, double data_range);

// Wang et al. 2004 SSIM, computed directly: for every valid 11×11 window,
// Gaussian-weighted (σ = 1.5, normalized 2-D) means, variances and
// covariance in double; mean of the map over channels and positions.
std::vector<double> ssim(std::span<const float> x, std::span<const float> y, std::int64_t n,
                         std::int64_t c, std::int64_t h, std::int64_t w, double data_range);

}  // namespace vkjr2::ref
