// Plain C++ reference of kernels/random (tests only): the same hash and
// Box–Muller arithmetic as shaders/random.glsl, in double.
#pragma once

#include <array>
#include <cstdint>
#include <span>

namespace vkjr2::ref {

std::array<std::uint32_t, 4> pcg4d(std::array<std::uint32_t, 4> v);
// The four normals of gaussian4(key).
std::array<double, 4> gaussian4(std::uint32_t group, std::uint32_t stream_id, std::uint64_t seed);
// Element i of kernels::randn(·, seed, stream_id, 0, 1).
double randn_at(std::uint64_t i, std::uint64_t seed, std::uint32_t stream_id);
void randn(std::span<float> out, std::uint64_t seed, std::uint32_t stream_id, float mean,
           float stddev);
void randn_ar1(std::span<float> x, float rho, std::uint64_t seed, std::uint32_t stream_id);
void sensor_noise(std::span<const float> x, std::span<float> y, float shot, float read_std,
                  std::uint64_t seed, std::uint32_t stream_id);

}  // namespace vkjr2::ref
