// Point-wise linear mixing of complex planes: turns K independent random
// fields (the real parts of inverse FFTs, kernels/fft.hpp layout) into K
// correlated ones, e.g. Zernike coefficient fields from unit-variance
// seeds and the Cholesky factor of their covariance (sim/field.hpp).
#pragma once

#include <vkjr2/runtime/stream.hpp>

#include <array>
#include <cstdint>

namespace vkjr2::kernels {

struct MixPlanesParams {
  std::int64_t batch = 1;             // B
  std::int64_t out_h = 0, out_w = 0;  // the top-left out_h × out_w corner of each plane
  float scale = 1.f;
  // first2 output: out[..., 0] · first2_scale[0], out[..., 1] · first2_scale[1].
  std::array<float, 2> first2_scale{1.f, 1.f};
};

// planes: [K·B, H, W, 2] complex, plane k of batch item b at index k·B + b;
// mix: [K, K] row-major; out: [B, K, out_h, out_w];
// out[b, i, y, x] = scale · Σ_k mix[i, k] · Re planes[k·B + b, y, x].
// first2 (optional, needs K ≥ 2): [B, 2, out_h, out_w] with
// first2[b, c, y, x] = first2_scale[c] · out[b, c, y, x].
void mix_planes(Stream& stream, const Tensor& planes, const Tensor& mix, const Tensor& out,
                const MixPlanesParams& params, const Tensor* first2 = nullptr);

}  // namespace vkjr2::kernels
