// The interface of a spatially varying blur written in a PSF basis, as the
// Simulator uses it: a basis ψ_k and the device computation of the weight maps
// β_k from Zernike coefficient maps. The trained P2S implementation is
// sim/p2s_blur_model.hpp.
#pragma once

#include <vkjr2/runtime/stream.hpp>

#include <memory>
#include <vector>

namespace vkjr2::sim {

// A spatially varying blur written in a PSF basis.
class BlurModel {
 public:
  virtual ~BlurModel() = default;
  // ψ: [K, S, S], S odd; ψ_0 is the mean PSF.
  virtual const Tensor& basis() const = 0;
  // The highest Noll index of the input coefficients (input: a_4..a_{j_max}).
  virtual int j_max() const = 0;
  // The sampling (Nyquist ratio λf/(2Dp)) the basis was made for.
  virtual double nyquist() const = 0;
  // coefficients [N, M, h, w] in radians, planes a_2..a_{M+1} with
  // M + 1 ≥ j_max (the model reads a_4..a_{j_max}) → beta [N, K, h, w].
  // The model sees coefficient_scale · coefficients: the Simulator passes
  // λ_0/λ_c to turn phase at channel 0's wavelength into phase at channel c's.
  virtual void weights(Stream& stream, const Tensor& coefficients, const Tensor& beta,
                       float coefficient_scale = 1.f) const = 0;
};

// The first of `models` made for a sampling within 2 % of `nyquist` (the
// mismatch a basis tolerates), or null: what the Simulator picks per channel.
std::shared_ptr<const BlurModel> blur_model_for(
    const std::vector<std::shared_ptr<const BlurModel>>& models, double nyquist);

}  // namespace vkjr2::sim
