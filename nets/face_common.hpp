// Shared plumbing of the face-api models (TF.js weights → our layouts, model
// location, images to device tensors).
#pragma once

#include <vkjr2/kernels/resize.hpp>
#include <vkjr2/nets/autograd.hpp>
#include <vkjr2/runtime/host_tensor.hpp>
#include <vkjr2/runtime/image.hpp>
#include <vkjr2/runtime/tensor.hpp>

#include <array>
#include <filesystem>
#include <set>
#include <string>
#include <vector>

namespace vkjr2::nets {

class TfjsWeights;

// Where face-api's model/ folder is: $VKJR2_FACE_API_DIR, else
// ${VKJR2_CACHE_DIR:-$HOME/.cache/vkjr2}/face-api-1.7.15/model. Throws a
// clear error ("run scripts/setup") when the folder or `manifest` in it is
// missing.
std::filesystem::path face_api_model_dir();
std::filesystem::path face_api_manifest(const char* manifest);

// TF.js conv filter [kh, kw, cin, cout] (HWIO) → our OIHW [cout, cin, kh, kw].
Tensor conv_weight_from_hwio(const Device& device, const HostTensor& hwio, const char* name);
// TF.js depthwise filter [kh, kw, c, multiplier] → [c·multiplier, 1, kh, kw]
// (output channel c·multiplier + m, as TF orders them).
Tensor depthwise_weight_from_hwio(const Device& device, const HostTensor& hwio, const char* name);
// A 1-D tensor (bias, scale) of `expected` elements.
Tensor vector_from(const Device& device, const HostTensor& v, std::int64_t expected,
                   const char* name);

// face-api's input normalization, (x − mean) / 255 per RGB channel, as a
// channel affine x · scale + shift (scale 1/255, shift −mean/255): the values
// and the Vars a model's forward applies.
struct InputAffine {
  std::vector<float> scale, shift;
  Var scale_var, shift_var;
};
InputAffine mean_rgb_affine(const Device& device, const std::array<float, 3>& mean_rgb);

// HWC (or 1×HWC) float image → device tensor [1, C, H, W]; and back
// (runtime/image.hpp, the one conversion every command uses).
using vkjr2::image_to_device;
using vkjr2::image_to_host;

// Takes a model's weights from its TF.js manifest by name, checking each
// shape and that none is used twice; finish() rejects weights the network
// left over (a manifest of another model). Errors name the weight, the file
// and the model.
class WeightReader {
 public:
  WeightReader(const TfjsWeights& weights, std::string model, std::string manifest);
  const HostTensor& take(const std::string& name, const std::vector<std::int64_t>& shape);
  Tensor conv(const Device& d, const std::string& name, const std::vector<std::int64_t>& shape);
  Tensor depthwise(const Device& d, const std::string& name, std::int64_t channels);
  Tensor vec(const Device& d, const std::string& name, std::int64_t n);
  void finish() const;

 private:
  [[noreturn]] void fail(const std::string& name, const std::string& problem) const;
  const TfjsWeights& weights_;
  std::string model_, manifest_;
  std::set<std::string> used_;
};

// JS Math.round of diff/2 for the non-negative differences padToSquare
// splits: ties go up (the larger half is padded after the image).
inline std::int64_t js_round_half(std::int64_t diff) { return (diff + 1) / 2; }

// The square canvas face-api's padToSquare builds around an h × w image
// (zeros split between both sides of the shorter axis, the larger half
// after), for kernels::resize_zero_padded and resize_into_padded.
kernels::ResizeCanvas square_canvas(std::int64_t h, std::int64_t w);

// A network's input in one pass (kernels::resize_into_padded): the image on
// `canvas`, resized with face-api's legacy bilinear to `shape` [N, C, S, S],
// normalized (·scale + shift per channel), written in `layout` (the first
// conv's ConvPlans::input_layout: no padding pass). nonfinite: set to a
// flag that reads, after the stream runs, 1 when any input value is NaN or
// infinite, else 0. Inference only (the result needs no gradient).
Var resize_normalized(Tape& t, const Tensor& image, const kernels::ResizeCanvas& canvas,
                      const Shape& shape, const Var& scale, const Var& shift,
                      const kernels::PlaneLayout& layout, Tensor& nonfinite);

// face-api's padToSquare(image, isCenterImage = true) (zeros, the larger half
// after the image), then, unless the side already is `size`, resizeBilinear
// (legacy) to size × size, for an NCHW batch. When nothing needs a gradient,
// one pass that never builds the square (kernels::resize_zero_padded); on a
// tape recording gradients for `image`, pad + resize.
Var pad_to_square_and_resize(Tape& t, const Var& image, std::int64_t size);

}  // namespace vkjr2::nets
