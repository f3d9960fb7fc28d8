// Counter-based Gaussian noise on the device: the seeds of the turbulence
// fields, their AR(1) evolution from frame to frame, and sensor noise.
//
// Contract (the same bits on every device up to float rounding of log):
// element i of a call with (seed, stream_id) is normal k = i mod 4 of
// gaussian4(i / 4, stream_id, seed) — the pcg4d hash of the four words
// (i / 4, stream_id, seed low 32 bits, seed high 32 bits), turned into four
// normals by Box–Muller (shaders/random.glsl). Nothing is stored between
// calls: the same (seed, stream_id) gives the same numbers, different
// stream ids give independent ones (e.g. one per frame).
#pragma once

#include <vkjr2/runtime/stream.hpp>

#include <cstdint>

namespace vkjr2::kernels {

// out = mean + stddev · n.
void randn(Stream& stream, const Tensor& out, std::uint64_t seed, std::uint32_t stream_id,
           float mean = 0.f, float stddev = 1.f);

// In place x ← ρ x + √(1 − ρ²) n, ρ in [0, 1]: a unit-variance AR(1) step
// (stationary variance 1 when x starts as standard normals).
void randn_ar1(Stream& stream, const Tensor& x, float rho, std::uint64_t seed,
               std::uint32_t stream_id);

// Poisson–Gaussian sensor noise in the heteroscedastic Gaussian form
// (Foi et al. 2008): y = x + √(shot · max(x, 0) + read_std²) · n, where
// shot = 1 / (photons per unit of x) and read_std is in units of x. x and y
// may be the same tensor.
void sensor_noise(Stream& stream, const Tensor& x, const Tensor& y, float shot, float read_std,
                  std::uint64_t seed, std::uint32_t stream_id);

}  // namespace vkjr2::kernels
