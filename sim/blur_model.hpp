// The P2S blur model for the Simulator: a trained PSF basis + P2S network
// (sim/p2s.hpp, made by `vkjr2 sim-train`) run on the device as a stack of
// 1×1 convolutions over the coefficient maps, so that β maps come out in
// the NCHW layout the PSF-basis convolution reads. The network's input
// scale is folded into the first layer and its output scale into the last.
#pragma once

#include <vkjr2/sim/p2s.hpp>
#include <vkjr2/sim/simulator.hpp>

#include <filesystem>
#include <memory>

namespace vkjr2::sim {

class P2sBlurModel : public BlurModel {
 public:
  P2sBlurModel(const Device& device, const P2sModel& model);
  const Tensor& basis() const override { return basis_; }
  int j_max() const override { return j_max_; }
  double nyquist() const override { return nyquist_; }
  // coefficients [N, M, h, w] = a_2..a_{M+1} (M + 1 ≥ j_max) → beta [N, K, h, w], β_0 = 1.
  // The first layer's weights for a new M are made on first use (not thread safe).
  void weights(Stream& stream, const Tensor& coefficients, const Tensor& beta) const override;

 private:
  const Tensor& first_layer(std::int64_t planes) const;
  Device device_;
  Tensor basis_;
  int j_max_, hidden_, count_;
  double nyquist_;
  std::vector<float> w1_host_;  // [hidden, j_max − 3]: input scale folded in
  mutable std::int64_t w1_planes_ = 0;
  mutable Tensor w1_;  // [hidden, M, 1, 1]: zero columns for a_2, a_3 and beyond a_{j_max}
  // [out, in, 1, 1] and [out]; the last layer has K outputs, row 0 all zero
  // with bias 1 (β_0 = 1).
  Tensor b1_, w2_, b2_, w3_, b3_;
};

// Loads a model file (load_p2s_model's checks and errors).
std::shared_ptr<const BlurModel> load_blur_model(const Device& device,
                                                 const std::filesystem::path& path);

// The shipped model for the presets' optics (artifacts/p2s_default.safetensors):
// $VKJR2_ARTIFACT_DIR, else the installed share/vkjr2, else the source tree.
std::filesystem::path default_blur_model_path();
std::shared_ptr<const BlurModel> load_default_blur_model(const Device& device);

}  // namespace vkjr2::sim
