#include <vkjr2/kernels/ref/random_ref.hpp>

#include <algorithm>
#include <cmath>
#include <numbers>

namespace vkjr2::ref {

std::array<std::uint32_t, 4> pcg4d(std::array<std::uint32_t, 4> v) {
  for (auto& e : v) e = e * 1664525u + 1013904223u;
  auto mix = [&v] {
    v[0] += v[1] * v[3];
    v[1] += v[2] * v[0];
    v[2] += v[0] * v[1];
    v[3] += v[1] * v[2];
  };
  mix();
  for (auto& e : v) e ^= e >> 16u;
  mix();
  return v;
}

std::array<double, 4> gaussian4(std::uint32_t group, std::uint32_t stream_id, std::uint64_t seed) {
  const auto h = pcg4d({group, stream_id, static_cast<std::uint32_t>(seed & 0xffffffffu),
                        static_cast<std::uint32_t>(seed >> 32)});
  constexpr double kUnit = 1.0 / 16777216.0;
  std::array<double, 4> u{};
  for (int k = 0; k < 4; ++k) u[k] = static_cast<double>(h[k] >> 8u) * kUnit;
  const double r0 = std::sqrt(-2.0 * std::log(u[0] + kUnit));
  const double r1 = std::sqrt(-2.0 * std::log(u[2] + kUnit));
  const double t0 = 2 * std::numbers::pi * u[1];
  const double t1 = 2 * std::numbers::pi * u[3];
  return {r0 * std::cos(t0), r0 * std::sin(t0), r1 * std::cos(t1), r1 * std::sin(t1)};
}

double randn_at(std::uint64_t i, std::uint64_t seed, std::uint32_t stream_id) {
  return gaussian4(static_cast<std::uint32_t>(i / 4), stream_id, seed)[i % 4];
}

void randn(std::span<float> out, std::uint64_t seed, std::uint32_t stream_id, float mean,
           float stddev) {
  for (std::size_t i = 0; i < out.size(); ++i)
    out[i] = static_cast<float>(mean + stddev * randn_at(i, seed, stream_id));
}

void randn_ar1(std::span<float> x, float rho, std::uint64_t seed, std::uint32_t stream_id) {
  const double innovation = std::sqrt(std::max(0.0, 1.0 - double(rho) * rho));
  for (std::size_t i = 0; i < x.size(); ++i)
    x[i] = static_cast<float>(rho * x[i] + innovation * randn_at(i, seed, stream_id));
}

void sensor_noise(std::span<const float> x, std::span<float> y, float shot, float read_std,
                  std::uint64_t seed, std::uint32_t stream_id) {
  for (std::size_t i = 0; i < x.size(); ++i) {
    const double sd = std::sqrt(std::max(0.0, double(x[i])) * shot + double(read_std) * read_std);
    y[i] = static_cast<float>(x[i] + sd * randn_at(i, seed, stream_id));
  }
}

}  // namespace vkjr2::ref
