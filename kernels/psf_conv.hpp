// PSF-basis convolution sum: the spatially varying blur of the turbulence
// simulator, written as K shift-invariant kernels ψ_k mixed by per-pixel
// weights β_k (Mao, Chimitt & Chan 2021; DESIGN.md "Frame formation"):
//   plain:       y_c = Σ_k ψ_k ⊛ (β_k ⊙ x_c)
//   normalized:  y_c = Σ_k ψ_k ⊛ (β_k ⊙ x_c) / Σ_k ψ_k ⊛ β_k
// ⊛ is true 2-D convolution, "same" output size, zero padding; ψ_k is centred
// at (S/2, S/2). The normalized form keeps brightness at the borders, where
// both numerator and denominator lose the same taps.
#pragma once

#include <vkjr2/runtime/stream.hpp>

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

}  // namespace vkjr2::kernels
