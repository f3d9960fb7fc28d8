// face-api's FaceRecognitionNet (dlib's ResNet-29 face descriptor: 150×150 RGB
// → 128-d, matched by Euclidean distance, threshold 0.6) on our differentiable
// ops, plus the crop face-api feeds it: the "dlib box" from 68 landmarks, the
// slice out of the frame, pad-to-square and the legacy bilinear resize.
//
// Spec: @vladmandic/face-api 1.7.15, src/faceRecognitionNet/*.ts,
// src/classes/FaceLandmarks.ts (alignDlib), src/classes/Box.ts
// (clipAtImageBorders), src/dom/extractFaceTensors.ts, src/ops/padToSquare.ts,
// src/dom/NetInput.ts (toBatchTensor). Every step is replicated exactly so the
// descriptors match face-api's to ~1e-5.
#pragma once

#include <vkjr2/nets/autograd.hpp>
#include <vkjr2/nets/face_box.hpp>
#include <vkjr2/nets/face_common.hpp>
#include <vkjr2/nets/ops.hpp>

#include <cstdint>
#include <filesystem>
#include <memory>
#include <span>
#include <vector>

namespace vkjr2::nets {

class TfjsWeights;

// NetInput.toBatchTensor(150, isCenterInputs = true) for one chip [N, 3, h, w]:
// zero-pad the shorter side to a square — round(diff/2) (JS Math.round, i.e.
// the larger half on odd diffs) after the image, the rest before it — then,
// unless already 150×150, resize with bilinear_legacy (src = dst·in/out).
// Pad + resize are differentiable ops, so pixel gradients flow back to the chip.
// A chip that is already 150×150 is returned as is (same Var / Tensor).
inline constexpr std::int64_t kRecognitionInputSize = 150;
Var to_recognition_input(Tape& t, const Var& chip_nchw);
// Same without a tape (inference).
Tensor to_recognition_input(Stream& stream, const Tensor& chip_nchw);

// The network. Parameter names mirror the TF.js weight names with '/' → '.'
// ("conv64_down.conv1.conv.filters"); filters are stored OIHW, fc [256, 128].
class FaceRecognitionNet : public Module {
 public:
  static constexpr std::int64_t kDescriptorSize = 128;
  static constexpr std::int64_t kParameterCount = 5'614'592;

  // Loads face-api's face_recognition_model from its TF.js manifest.
  static std::unique_ptr<FaceRecognitionNet> load(
      const Device& device, const std::filesystem::path& manifest =
                                face_api_manifest("face_recognition_model-weights_manifest.json"));
  // Builds from already-read weights. Throws InvalidArgument naming the weight
  // when one is missing or has the wrong shape, and when the manifest holds a
  // weight this network does not use (every tensor is consumed exactly once).
  FaceRecognitionNet(const Device& device, const TfjsWeights& weights);
  ~FaceRecognitionNet() override;

  // rgb [N, 3, 150, 150], RGB in 0..255 (exactly what face-api feeds after its
  // resize) → descriptors [N, 128]. Inside: (rgb − [122.782, 117.001,
  // 104.298]) / 255, then the ResNet. Differentiable w.r.t. rgb and the
  // parameters. Throws InvalidArgument for any other input shape.
  Var forward(Tape& t, const Var& rgb) const;
  // Inference: forward on a non-recording tape; descriptors [N, 128] (the
  // work is recorded on `stream`; run it before reading the result).
  Tensor describe(Stream& stream, const Tensor& rgb) const;

  // Marks every parameter as (not) needing a gradient: a frozen embedder
  // still passes gradients to its input but computes no weight gradients.
  void set_frozen(bool frozen) const;

 private:
  class ConvLayer;
  class Residual;
  ConvLayer* conv32_down_ = nullptr;
  std::vector<const Residual*> blocks_;
  Var fc_;
  Var input_scale_, input_shift_;  // 1/255 and −mean/255 per channel
};

}  // namespace vkjr2::nets
