// PSF-basis convolution sum: the spatially varying blur of the turbulence
// simulator, written as K shift-invariant kernels ψ_k mixed by per-pixel
// weights β_k (Mao, Chimitt & Chan 2021; DESIGN.md "Frame formation"):
//   plain:       y_c = Σ_k ψ_k ⊛ (β_k ⊙ x_c)
//   normalized:  y_c = Σ_k ψ_k ⊛ (β_k ⊙ x_c) / Σ_k ψ_k ⊛ β_k
// ⊛ is true 2-D convolution, "same" output size, zero padding; ψ_k is centred
// at (S/2, S/2). The normalized form keeps brightness at the borders, where
// both numerator and denominator lose the same taps.
#pragma once

#include <vkjr2/kernels/fft.hpp>
#include <vkjr2/runtime/stream.hpp>

#include <cstdint>
#include <memory>

namespace vkjr2::kernels {

struct PsfConvParams {
  bool normalize = false;
};

// x [N, C, H, W] with C in 1..4; beta [N, K, H, W]; psi [K, S, S] with S odd.
// Writes y [N, C, H, W] and norm [N, 1, H, W] = Σ_k ψ_k ⊛ β_k (kept for the
// backward of the normalized form).
void psf_conv(Stream& stream, const Tensor& x, const Tensor& beta, const Tensor& psi,
              const Tensor& y, const Tensor& norm, PsfConvParams params = {});

// Gradients of L w.r.t. x and beta given dy = dL/dy. For the normalized form,
// y and norm must be the forward's outputs.
void psf_conv_backward(Stream& stream, const Tensor& x, const Tensor& beta, const Tensor& psi,
                       const Tensor& y, const Tensor& norm, const Tensor& dy, const Tensor& dx,
                       const Tensor& dbeta, PsfConvParams params = {});

// FFT path of the forward (the same y and norm as psf_conv, to float
// rounding): one r2c per product image β_k ⊙ x_c (and per β_k for the
// normalization), the sum over k taken in the frequency domain against the
// basis' spectra Ψ̂_k, one c2r per channel:
//   y_c = F⁻¹[Σ_k Ψ̂_k · F(β_k ⊙ x_c)],  norm = F⁻¹[Σ_k Ψ̂_k · F(β_k)]
// on a zero-padded Hp × Wp grid (Hp ≥ H + S − 1: no wrap-around), k taken in
// chunks so that no temporary exceeds 96 MiB. The spectra Ψ̂_k are made once,
// for one ψ and one image shape. When k needs more than one chunk (large
// images), forward() submits and waits for the stream between chunks, so
// that one chunk's temporaries are released before the next is taken.
class PsfConvFft {
 public:
  // psi [K, S, S]; images [batch, channels, height, width].
  // max_temporary_bytes bounds each temporary (k is chunked to fit); 0: the
  // device's DeviceTraits::psf_fft_max_temporary_bytes.
  PsfConvFft(const Device& device, const Tensor& psi, std::int64_t batch, std::int64_t channels,
             std::int64_t height, std::int64_t width, std::int64_t max_temporary_bytes = 0);
  ~PsfConvFft();
  PsfConvFft(const PsfConvFft&) = delete;
  PsfConvFft& operator=(const PsfConvFft&) = delete;
  void forward(Stream& stream, const Tensor& x, const Tensor& beta, const Tensor& y,
               const Tensor& norm, PsfConvParams params = {}) const;
  std::int64_t padded_height() const { return hp_; }
  std::int64_t padded_width() const { return wp_; }
  std::int64_t chunk() const { return chunk_; }  // kernels per pass

 private:
  Device device_;
  std::int64_t n_, c_, k_, s_, h_, w_, hp_, wp_, chunk_;
  Tensor psi_hat_;  // [K, Hp, Wp/2+1, 2]
  std::unique_ptr<FftPlan> forward_, forward_last_, inverse_;
};

// Which path is cheaper for these shapes on a device, by the cost model in
// its DeviceTraits (measured on lavapipe; docs/sim.md §7): the direct path's
// work grows as K·S² per pixel, the FFT path's as K·(C + 1)·log(Hp·Wp).
enum class PsfConvPath : std::uint8_t { direct, fft };
PsfConvPath psf_conv_path(const DeviceTraits& traits, std::int64_t n, std::int64_t c,
                          std::int64_t k, std::int64_t s, std::int64_t h, std::int64_t w);

}  // namespace vkjr2::kernels
