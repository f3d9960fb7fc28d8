// Plain C++ references of kernels/fft (tests and benchmarks only): a
// double-precision recursive mixed-radix FFT (naive DFT for prime lengths),
// independent of the device's Stockham passes and of FFTW.
#pragma once

#include <complex>
#include <cstdint>
#include <span>
#include <vector>

namespace vkjr2::ref {

// In-place 1-D DFT of n elements spaced `stride` apart; sign −1 (forward) or
// +1 (inverse), unnormalized.
void dft1d(std::complex<double>* data, std::int64_t n, std::int64_t stride, int sign);

// 2-D c2c of [batch, h, w] complex values stored as (re, im) floats;
// unnormalized, sign −1 forward, +1 inverse. Returns (re, im) doubles.
std::vector<double> fft2d_c2c(std::span<const float> x, std::int64_t batch, std::int64_t h,
                              std::int64_t w, bool inverse);

// 2-D r2c of real [batch, h, w]: half spectrum [batch, h, w/2+1] as (re, im).
std::vector<double> fft2d_r2c(std::span<const float> x, std::int64_t batch, std::int64_t h,
                              std::int64_t w);

}  // namespace vkjr2::ref
