// The P2S blur model for the Simulator: a trained PSF basis + P2S network
// (sim/p2s.hpp, made by `vkjr2 sim-train`) run on the device as a stack of
// 1×1 convolutions over the coefficient maps, so that β maps come out in
// the NCHW layout the PSF-basis convolution reads. The network's input
// scale is folded into the first layer and its output scale into the last.
#pragma once

#include <vkjr2/sim/blur_model.hpp>
#include <vkjr2/sim/p2s.hpp>

#include <filesystem>
#include <memory>
#include <vector>

namespace vkjr2::sim {

class P2sBlurModel : public BlurModel {
 public:
  P2sBlurModel(const Device& device, const P2sModel& model);
  const Tensor& basis() const override { return basis_; }
  int j_max() const override { return j_max_; }
  double nyquist() const override { return nyquist_; }
  // coefficients [N, M, h, w] = a_2..a_{M+1} (M + 1 ≥ j_max) → beta [N, K, h, w], β_0 = 1.
  // coefficient_scale is folded into the first layer. Its weights for a new
  // (M, scale) are made on first use and kept (not thread safe).
  void weights(Stream& stream, const Tensor& coefficients, const Tensor& beta,
               float coefficient_scale = 1.f) const override;

 private:
  const Tensor& first_layer(std::int64_t planes, float scale) const;
  Device device_;
  Tensor basis_;
  int j_max_, hidden_, count_;
  double nyquist_;
  std::vector<float> w1_host_;  // [hidden, j_max − 3]: input scale folded in
  struct FirstLayer {
    std::int64_t planes;
    float scale;
    Tensor weight;  // [hidden, M, 1, 1]: zero columns for a_2, a_3 and beyond a_{j_max}
  };
  mutable std::vector<FirstLayer> w1_;
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

// Every shipped model: p2s_*.safetensors in the folder of
// default_blur_model_path(), p2s_default first, then by name. Besides the
// presets' 525 nm they hold 610 nm and 465 nm for the same optics, so an RGB
// image with optics.wavelengths_m = {610e-9, 525e-9, 465e-9} (kRgbWavelengthsM)
// blurs each channel at its own wavelength.
std::vector<std::filesystem::path> shipped_blur_model_paths();
std::vector<std::shared_ptr<const BlurModel>> load_shipped_blur_models(const Device& device);

// The wavelengths the shipped models cover for an RGB image (R, G, B), in metres.
inline constexpr double kRgbWavelengthsM[3] = {610e-9, 525e-9, 465e-9};

}  // namespace vkjr2::sim
