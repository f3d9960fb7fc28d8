// 2-D FFTs on the device: batched complex-to-complex, and real-to-complex
// with its inverse complex-to-real. Our own mixed-radix Stockham shaders
// (shaders/fft_common.glsl); lengths are products of 2, 3, 5 and 7.
//
// Layout: a complex tensor of logical shape [B, H, W] is a float32 Tensor of
// shape [B, H, W, 2], (re, im) interleaved. A real input [B, H, W] has the
// half spectrum [B, H, W/2 + 1, 2] (FFTW's r2c layout). Plans built from a
// rank-2 shape {H, W} drop the batch axis from every tensor shape.
//
// Conventions (those of FFTW and numpy):
//   forward  X[u, v] = Σ_{y,x} x[y, x] · exp(-2πi (u y / H + v x / W))   (sign −1)
//   inverse  x[y, x] = s · Σ_{u,v} X[u, v] · exp(+2πi (u y / H + v x / W)) (sign +1)
// with the scale s (and the forward's) set by FftNorm. With FftNorm::backward
// inverse(forward(x)) = x.
//
// Gradients: the FFT is linear, so no backward kernel exists. The adjoint of
// the unnormalized forward F is Fᴴ = N · (backward-normalized inverse) = the
// FftNorm::none inverse, N = H · W: backprop of a c2c forward maps the output
// gradient g (as (re, im) pairs) to Fᴴ g. For r2c, the input gradient is the
// unnormalized c2r of g with the bins 0 < v < W/2 halved (DC and, for even W,
// Nyquist kept), since c2r counts each of those bins twice.
//
// A NaN in an image makes every output of that image NaN (in the real or the
// imaginary part or both); other images of the batch are unaffected.
#pragma once

#include <vkjr2/runtime/stream.hpp>

#include <cstdint>
#include <vector>

namespace vkjr2::kernels {

enum class FftKind : std::uint8_t {
  c2c,  // complex [B, H, W, 2] ↔ complex [B, H, W, 2]
  r2c,  // forward: real [B, H, W] → [B, H, W/2+1, 2]; inverse (c2r): back to real
};

enum class FftNorm : std::uint8_t {
  backward,  // forward unscaled, inverse scaled by 1 / (H · W)   (default)
  none,      // neither scaled: inverse(forward(x)) = H · W · x
  ortho,     // both scaled by 1 / sqrt(H · W) (unitary)
};

// True when n ≥ 1 is a product of 2, 3, 5 and 7 (a length the FFT supports).
bool fft_supported_length(std::int64_t n);
// The smallest supported length ≥ n (pad to it, e.g. for FFT convolution).
std::int64_t fft_next_length(std::int64_t n);

// A plan for one shape and kind: the pass list and twiddle tables, built once
// and reused by any number of calls (and streams). Temporaries are taken per
// call with Tensor::empty and kept alive by the stream.
class FftPlan {
 public:
  // shape: {B, H, W} or {H, W}; every axis ≥ 1, H and W supported lengths.
  FftPlan(const Device& device, const Shape& shape, FftKind kind, FftNorm norm = FftNorm::backward);

  // c2c: in, out [B, H, W, 2]. r2c: in real [B, H, W], out [B, H, W/2+1, 2].
  // in and out may be the same tensor (c2c).
  void forward(Stream& stream, const Tensor& in, const Tensor& out) const;
  // c2c: in, out [B, H, W, 2]. r2c plan (c2r): in [B, H, W/2+1, 2], out real
  // [B, H, W]; the imaginary parts of bins that must be real (DC, Nyquist)
  // are ignored, as in FFTW.
  void inverse(Stream& stream, const Tensor& in, const Tensor& out) const;

  // The shapes forward() takes and gives (inverse() the other way round).
  const Shape& signal_shape() const { return signal_shape_; }
  const Shape& spectrum_shape() const { return spectrum_shape_; }
  FftKind kind() const { return kind_; }
  FftNorm norm() const { return norm_; }
  // Radices of the row (W) and column (H) passes, in order.
  const std::vector<std::uint32_t>& row_radices() const { return row_radices_; }
  const std::vector<std::uint32_t>& column_radices() const { return column_radices_; }

 private:
  void run(Stream& stream, const Tensor& in, const Tensor& out, bool inverse) const;

  Device device_;
  FftKind kind_;
  FftNorm norm_;
  std::uint32_t batch_ = 1, height_ = 1, width_ = 1;
  Shape signal_shape_, spectrum_shape_;
  std::vector<std::uint32_t> row_radices_, column_radices_;
  Tensor row_twiddles_, column_twiddles_;  // RG32F exp(-2πi t / n), t in [0, n)
};

// One-shot 2-D c2c FFT of [B, H, W, 2] (or [H, W, 2]); builds a plan per call.
void fft2(Stream& stream, const Tensor& in, const Tensor& out, bool inverse,
          FftNorm norm = FftNorm::backward);

// For host data: uploads `data` (complex [B, H, W, 2] for shape {B, H, W}),
// runs one batched c2c FFT on the device, waits, and downloads the result
// into `data`.
void fft2_host(const Device& device, const Shape& shape, std::vector<float>& data, bool inverse,
               FftNorm norm = FftNorm::backward);

}  // namespace vkjr2::kernels
