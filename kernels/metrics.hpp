// Image quality metrics, batched over NCHW images: PSNR and SSIM (Wang,
// Bovik, Sheikh, Simoncelli 2004), and the SSIM gradient for use as a loss.
#pragma once

#include <vkjr2/runtime/stream.hpp>

namespace vkjr2::kernels {

// psnr[n] = 10·log10(L² / mse[n]), mse[n] = mean over C·H·W of (a − b)².
// a, b: [N, C, H, W]; out: [N]. Identical images give +inf (mse = 0); NaN
// inputs give NaN. L = data_range (1 for [0, 1] images, 255 for 8-bit).
void psnr(Stream& stream, const Tensor& a, const Tensor& b, float data_range, const Tensor& out);

// SSIM exactly as Wang et al. 2004 (their MATLAB ssim_index): 11×11 Gaussian
// window, σ = 1.5, normalized; C1 = (0.01 L)², C2 = (0.03 L)²; local means,
// variances and covariance by the Gaussian filter (population form:
// E[x²] − μ², no sample correction); the SSIM map over the valid region only
// ((H − 10) × (W − 10), no padding); its mean per channel, and for colour the
// mean over channels. x, y: [N, C, H, W] with H, W ≥ 11; out: [N].
// Separable: two 1-D passes, then a per-image mean; deterministic.
void ssim(Stream& stream, const Tensor& x, const Tensor& y, float data_range, const Tensor& out);

// dx = d_ssim[n] · ∂ssim[n]/∂x (y is held fixed). d_ssim: [N]; dx: x's shape.
// For an SSIM loss L = Σ_n w_n (1 − ssim[n]) pass d_ssim = −w.
void ssim_backward(Stream& stream, const Tensor& x, const Tensor& y, float data_range,
                   const Tensor& d_ssim, const Tensor& dx);

}  // namespace vkjr2::kernels
