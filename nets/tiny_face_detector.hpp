// face-api's TinyFaceDetector (a tiny-YOLOv2 with depthwise-separable convs,
// one class, 5 anchors) on our differentiable ops, plus the steps face-api
// takes around it: the image → input (NetInput.toBatchTensor with
// isCenterInputs = false: zero padding at the bottom/right to a square, then
// legacy bilinear resize), the box decoding (TinyYolov2Base.extractBoxes) and
// non-maximum suppression (ops/nonMaxSuppression.ts).
//
// Spec: @vladmandic/face-api 1.7.15, src/tinyFaceDetector/*.ts,
// src/tinyYolov2/{TinyYolov2Base,depthwiseSeparableConv,leaky,
// extractParamsFromWeightMap,TinyYolov2Options}.ts, src/ops/{iou,
// nonMaxSuppression,padToSquare}.ts, src/dom/NetInput.ts,
// src/utils/index.ts (computeReshapedDimensions).
#pragma once

#include <vkjr2/nets/autograd.hpp>
#include <vkjr2/nets/face_box.hpp>
#include <vkjr2/nets/face_common.hpp>
#include <vkjr2/nets/ops.hpp>
#include <vkjr2/nets/separable_conv.hpp>

#include <array>
#include <filesystem>
#include <memory>
#include <span>
#include <vector>

namespace vkjr2::nets {

class TfjsWeights;

struct FaceDetection {
  float score = 0;  // σ(objectness)
  FaceBox box;      // image pixels
};

// One decoded grid cell/anchor that passed the score threshold (extractBoxes).
struct TinyYoloCandidate {
  int row = 0, col = 0, anchor = 0;
  double score = 0;  // σ(objectness), computed in double as face-api does
  FaceBox relative;  // x, y, width, height as fractions of the image
};

inline constexpr int kTinyYoloAnchors = 5;
inline constexpr int kTinyYoloBoxEncoding = 5;  // tx, ty, tw, th, objectness
// tinyFaceDetector/const.ts: anchors in grid cells, IoU threshold of the NMS.
inline constexpr std::array<std::array<double, 2>, kTinyYoloAnchors> kTinyFaceAnchors = {{
    {1.603231, 2.094468},
    {6.041143, 7.080126},
    {2.882459, 3.518061},
    {4.266906, 5.178857},
    {9.041765, 10.66308},
}};
inline constexpr double kTinyFaceIouThreshold = 0.4;

// computeReshapedDimensions: the image's size inside the padded input square,
// {round(w·s), round(h·s)} with s = input_size / max(w, h) (JS Math.round).
std::array<int, 2> tiny_yolo_reshaped_size(int image_w, int image_h, int input_size);

// extractBoxes over one image's raw output [25, cells, cells] (NCHW, channel
// anchor·5 + k; k = tx, ty, tw, th, objectness): keeps σ(obj) > score_threshold
// (every box when the threshold is 0), in row, col, anchor order. Boxes are
// relative to the image: cell units / cells, corrected by input_size /
// reshaped size for the padding at the bottom/right.
std::vector<TinyYoloCandidate> decode_tiny_yolo(std::span<const float> output, int cells,
                                                std::array<int, 2> reshaped_wh,
                                                double score_threshold);

// face-api's nonMaxSuppression: candidates by descending score (ties: the later
// index first, as its ascending sort + pop does); a box is dropped when its IoU
// (intersection / union) with a kept box exceeds iou_threshold. Returns the
// kept indices in the order they were picked.
std::vector<std::size_t> non_max_suppression(std::span<const FaceBox> boxes,
                                             std::span<const double> scores, double iou_threshold);

class TinyFaceDetector : public Module {
 public:
  static constexpr std::int64_t kParameterCount = 193'321;
  static constexpr std::int64_t kOutputChannels = kTinyYoloAnchors * kTinyYoloBoxEncoding;

  // Loads face-api's tiny_face_detector_model from its TF.js manifest.
  static std::unique_ptr<TinyFaceDetector> load(
      const Device& device, const std::filesystem::path& manifest = face_api_manifest(
                                "tiny_face_detector_model-weights_manifest.json"));
  // Builds from already-read weights. Throws InvalidArgument naming the weight
  // when one is missing, has the wrong shape, or is not used by this network.
  TinyFaceDetector(const Device& device, const TfjsWeights& weights);
  ~TinyFaceDetector() override;

  // x [N, 3, S, S], RGB 0..255, S a positive multiple of 32 (what face-api
  // feeds after padding and resizing) → raw output [N, 25, S/32, S/32].
  // Inside: (rgb − [117.001, 114.697, 97.404]) / 255; conv0 3×3 valid +
  // leaky 0.1; max pool 2×2/2 "same"; conv1–5 depthwise-separable (pad 1) +
  // leaky 0.1, each followed by a max pool 2×2 "same" (stride 2, the last
  // stride 1); conv8 1×1. Differentiable. Throws InvalidArgument otherwise.
  Var forward(Tape& t, const Var& x) const;

  // NetInput.toBatchTensor(input_size, false) for one image [1, 3, H, W]:
  // zero padding at the bottom or right to a square, then (unless already
  // input_size²) a bilinear_legacy resize. The full-size square is never
  // built (see the .cpp). Throws InvalidArgument for a bad image or input size.
  Tensor preprocess(Stream& stream, const Tensor& image_nchw, int input_size) const;

  // face-api's TinyFaceDetector.locateFaces: detections in image pixels, in
  // the order NMS picked them (highest score first). image_nchw: [1, 3, H, W]
  // RGB 0..255. input_size: a positive multiple of 32; score_threshold in
  // (0, 1) as TinyYolov2Options requires. Bad arguments throw InvalidArgument.
  std::vector<FaceDetection> detect(Stream& stream, const Tensor& image_nchw, int input_size = 416,
                                    float score_threshold = 0.5f) const;

 private:
  static kernels::Conv2dParams conv0_params();
  // The network after the input normalization (x: plain, or in conv0's
  // input layout).
  Var body(Tape& t, const Var& x) const;

  Var conv0_filters_, conv0_bias_;
  std::vector<const SeparableConv3x3*> convs_;  // conv1 … conv5
  Var conv8_filters_, conv8_bias_;
  ConvPlans conv0_plans_, conv8_plans_;
  Var input_scale_, input_shift_;  // 1/255 and −mean/255 per channel
};

}  // namespace vkjr2::nets
