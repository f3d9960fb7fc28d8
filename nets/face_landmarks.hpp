// face-api's FaceLandmark68Net (68-point landmarks from a 112×112 face crop)
// on our differentiable ops, plus the steps face-api takes around it: the
// detection box → crop (extractFaceTensors), the crop → 112×112 input
// (NetInput.toBatchTensor, centred zero padding + legacy bilinear resize) and
// the 136 outputs → pixels (FaceLandmark68NetBase.postProcess, then the shift
// by the detection box in extendWithFaceLandmarks).
//
// Spec: @vladmandic/face-api 1.7.15, src/faceLandmarkNet/*.ts,
// src/faceFeatureExtractor/{FaceFeatureExtractor,denseBlock}.ts,
// src/faceProcessor/FaceProcessor.ts, src/common/depthwiseSeparableConv.ts,
// src/ops/{normalize,padToSquare}.ts, src/dom/{NetInput,extractFaceTensors}.ts,
// src/classes/{Box,FaceLandmarks}.ts.
#pragma once

#include <vkjr2/nets/autograd.hpp>
#include <vkjr2/nets/face_common.hpp>
#include <vkjr2/nets/face_recognition.hpp>  // FaceBox, clip_at_image_borders, extract_face
#include <vkjr2/nets/ops.hpp>

#include <array>
#include <filesystem>
#include <memory>
#include <vector>

namespace vkjr2::nets {

class TfjsWeights;

inline constexpr std::int64_t kLandmarkInputSize = 112;
inline constexpr int kLandmarkCount = 68;

// NetInput.toBatchTensor(112, isCenterInputs = true) for face crops
// [N, 3, h, w] (RGB 0..255): zero-pad the shorter side to a square —
// round(diff/2) (JS Math.round: the larger half on odd diffs) after the image,
// the rest before it — then, unless already 112×112, resize with
// bilinear_legacy. Differentiable (pad + resize ops).
Var to_landmark_input(Tape& t, const Var& crop_nchw);

// FaceLandmark68NetBase.postProcess for one crop of crop_w × crop_h pixels:
// raw [136] (x0, y0, x1, y1, … in [0, 1] of the padded 112² square) →
// positions relative to the crop, in float32 arithmetic as TF.js does:
// (raw·112 − pad) / scaled_size, where the crop is scaled by 112/max(w, h)
// and pad = |scaled_w − scaled_h| / 2 on the shorter axis (face-api's own
// estimate of the padding, not the integer pixels padToSquare added).
std::array<float, 2 * kLandmarkCount> landmarks_relative_to_crop(const float* raw136, double crop_w,
                                                                 double crop_h);

class FaceLandmark68Net : public Module {
 public:
  static constexpr std::int64_t kOutputs = 2 * kLandmarkCount;
  static constexpr std::int64_t kParameterCount = 356'840;

  // Loads face-api's face_landmark_68_model from its TF.js manifest.
  static std::unique_ptr<FaceLandmark68Net> load(
      const Device& device, const std::filesystem::path& manifest =
                                face_api_manifest("face_landmark_68_model-weights_manifest.json"));
  // Builds from already-read weights. Throws InvalidArgument naming the weight
  // when one is missing, has the wrong shape, or is not used by this network
  // (every manifest tensor is consumed exactly once).
  FaceLandmark68Net(const Device& device, const TfjsWeights& weights);
  ~FaceLandmark68Net() override;

  // x112 [N, 3, 112, 112], RGB 0..255 (what face-api feeds after its resize)
  // → raw outputs [N, 136]. Inside: (rgb − [122.782, 117.001, 104.298]) / 255,
  // four dense blocks, avgpool 7×7/2 valid, fc 256 → 136. Differentiable.
  // Throws InvalidArgument for any other input shape.
  Var forward(Tape& t, const Var& x112) const;

  // What face-api's detectLandmarks does with one face crop [1, 3, h, w]
  // (RGB 0..255): pad + resize to 112, run, postProcess. Returns 136 values
  // x0, y0, … in crop pixels (relative position × crop size).
  std::vector<float> detect_landmarks(Stream& stream, const Tensor& face_crop_nchw) const;

  // The 68 landmarks face-api reports for a detection `box` in image pixels:
  // the crop is the box clipped to the image and floored (clip_at_image_borders,
  // as extractFaceTensors takes it), the landmarks relative to the crop are
  // scaled by the crop size and shifted by the box's unfloored top-left corner
  // (extendWithFaceLandmarks). image_nchw: [1, 3, H, W] RGB 0..255. Returns
  // 136 values x0, y0, … (double, as face-api computes them). Throws
  // InvalidArgument when the box does not overlap the image.
  std::vector<double> landmarks_in_image(Stream& stream, const Tensor& image_nchw,
                                         const FaceBox& box) const;

 private:
  class DenseBlock;
  std::vector<const DenseBlock*> blocks_;
  Var fc_weights_, fc_bias_;
  Var input_scale_, input_shift_;  // 1/255 and −mean/255 per channel

  // Crop [1, 3, h, w] → landmarks relative to the crop (postProcess output).
  std::array<float, kOutputs> relative_landmarks(Stream& stream, const Tensor& crop) const;
  // The network after the input normalization (x: plain, or in the first
  // conv's input layout).
  Var body(Tape& t, const Var& x) const;
};

}  // namespace vkjr2::nets
