#include <vkjr2/kernels/resize.hpp>
#include <vkjr2/nets/tfjs_weights.hpp>
#include <vkjr2/nets/tiny_face_detector.hpp>
#include <vkjr2/runtime/error.hpp>

#include <algorithm>
#include <cmath>
#include <numeric>
#include <set>
#include <string>

namespace vkjr2::nets {
namespace {

namespace k = kernels;

// tinyFaceDetector/const.ts MEAN_RGB; TinyYolov2Base.forwardInput subtracts
// it, then divides by 255.
constexpr std::array<float, 3> kMeanRgb = {117.001f, 114.697f, 97.404f};
// leaky.ts: relu(x − 0.1x) + 0.1x, i.e. LeakyReLU with slope float32(0.1).
constexpr float kLeakySlope = 0.1f;

std::string shape_of(const Var& x) {
  return x.defined() ? x.shape().str() : std::string("(undefined)");
}

double sigmoid(double x) { return 1.0 / (1.0 + std::exp(-x)); }

// JS Math.round for non-negative values: ties go up.
int js_round(double v) { return int(std::floor(v + 0.5)); }

void require_input_size(int input_size, const char* op) {
  if (input_size <= 0 || input_size % 32 != 0) {
    throw InvalidArgument(
        op, "input_size " + std::to_string(input_size) + " is not a positive multiple of 32",
        "use 416 (face-api's default), or another multiple of 32 such as 320 "
        "(faster) or 608 (finds smaller faces)");
  }
}

void require_image(const Tensor& image, const char* op) {
  const bool ok = image.defined() && image.shape().rank() == 4 && image.shape()[0] == 1 &&
                  image.shape()[1] == 3 && image.numel() > 0 && image.dtype() == DType::f32;
  if (!ok) {
    throw InvalidArgument(
        op,
        "image_nchw has shape " +
            (image.defined() ? image.shape().str() : std::string("(undefined)")) +
            ", expected one non-empty f32 RGB image [1, 3, H, W]",
        "pass one decoded image (image_to_device gives [1, 3, H, W], RGB 0..255)");
  }
}

}  // namespace

// ---- decoding and NMS ---------------------------------------------------------------

std::array<int, 2> tiny_yolo_reshaped_size(int image_w, int image_h, int input_size) {
  if (image_w <= 0 || image_h <= 0) {
    throw InvalidArgument(
        "tiny_yolo_reshaped_size",
        "image size " + std::to_string(image_w) + "×" + std::to_string(image_h) + " is empty",
        "pass the width and height of a non-empty image");
  }
  require_input_size(input_size, "tiny_yolo_reshaped_size");
  const double scale = double(input_size) / double(std::max(image_w, image_h));
  return {js_round(image_w * scale), js_round(image_h * scale)};
}

std::vector<TinyYoloCandidate> decode_tiny_yolo(std::span<const float> output, int cells,
                                                std::array<int, 2> reshaped_wh,
                                                double score_threshold) {
  const auto expected = std::size_t(TinyFaceDetector::kOutputChannels) * std::size_t(cells) *
                        std::size_t(std::max(cells, 0));
  if (cells <= 0 || output.size() != expected) {
    throw InvalidArgument("decode_tiny_yolo",
                          "output holds " + std::to_string(output.size()) + " values for " +
                              std::to_string(cells) + "×" + std::to_string(cells) + " cells",
                          "pass one image's raw detector output [25, cells, cells]");
  }
  if (reshaped_wh[0] <= 0 || reshaped_wh[1] <= 0) {
    throw InvalidArgument("decode_tiny_yolo", "reshaped size is not positive",
                          "pass tiny_yolo_reshaped_size(image_w, image_h, input_size)");
  }
  // extractBoxes: the padded square is max(w, h) of the reshaped image; boxes
  // relative to the square are stretched back to the image.
  const double input_size = std::max(reshaped_wh[0], reshaped_wh[1]);
  const double correction_x = input_size / reshaped_wh[0];
  const double correction_y = input_size / reshaped_wh[1];
  const auto plane = std::size_t(cells) * std::size_t(cells);
  const auto at = [&](int anchor, int k, int row, int col) {
    return double(output[std::size_t(anchor * kTinyYoloBoxEncoding + k) * plane +
                         std::size_t(row) * std::size_t(cells) + std::size_t(col)]);
  };
  std::vector<TinyYoloCandidate> out;
  for (int row = 0; row < cells; ++row) {
    for (int col = 0; col < cells; ++col) {
      for (int anchor = 0; anchor < kTinyYoloAnchors; ++anchor) {
        const double score = sigmoid(at(anchor, 4, row, col));
        if (score_threshold != 0 && !(score > score_threshold)) continue;
        const auto& a = kTinyFaceAnchors[std::size_t(anchor)];
        const double ct_x = ((col + sigmoid(at(anchor, 0, row, col))) / cells) * correction_x;
        const double ct_y = ((row + sigmoid(at(anchor, 1, row, col))) / cells) * correction_y;
        const double w = ((std::exp(at(anchor, 2, row, col)) * a[0]) / cells) * correction_x;
        const double h = ((std::exp(at(anchor, 3, row, col)) * a[1]) / cells) * correction_y;
        const double x = ct_x - w / 2, y = ct_y - h / 2;
        // BoundingBox(x, y, x + w, y + h) → Box: width = right − left.
        out.push_back({row, col, anchor, score, FaceBox{x, y, (x + w) - x, (y + h) - y}});
      }
    }
  }
  return out;
}

std::vector<std::size_t> non_max_suppression(std::span<const FaceBox> boxes,
                                             std::span<const double> scores, double iou_threshold) {
  if (boxes.size() != scores.size()) {
    throw InvalidArgument(
        "non_max_suppression",
        std::to_string(boxes.size()) + " boxes but " + std::to_string(scores.size()) + " scores",
        "pass one score per box");
  }
  // Ascending stable sort, then pop from the back: highest score first, and
  // among equal scores the later index first.
  std::vector<std::size_t> order(boxes.size());
  std::iota(order.begin(), order.end(), std::size_t(0));
  std::stable_sort(order.begin(), order.end(),
                   [&](std::size_t a, std::size_t b) { return scores[a] < scores[b]; });
  std::vector<std::size_t> pick;
  while (!order.empty()) {
    const std::size_t curr = order.back();
    order.pop_back();
    pick.push_back(curr);
    std::erase_if(
        order, [&](std::size_t i) { return !(box_iou(boxes[curr], boxes[i]) <= iou_threshold); });
  }
  return pick;
}

// ---- the network -------------------------------------------------------------------

std::unique_ptr<TinyFaceDetector> TinyFaceDetector::load(const Device& device,
                                                         const std::filesystem::path& manifest) {
  return std::make_unique<TinyFaceDetector>(device, load_tfjs_weights(manifest));
}

TinyFaceDetector::TinyFaceDetector(const Device& device, const TfjsWeights& weights) {
  WeightReader r(weights, "TinyFaceDetector", "tiny_face_detector_model");
  conv0_filters_ =
      register_parameter("conv0.filters", r.conv(device, "conv0/filters", {3, 3, 3, 16}));
  conv0_bias_ = register_parameter("conv0.bias", r.vec(device, "conv0/bias", 16));
  constexpr std::array<std::int64_t, 6> channels = {16, 32, 64, 128, 256, 512};
  for (std::size_t i = 0; i + 1 < channels.size(); ++i) {
    const std::string name = "conv" + std::to_string(i + 1);
    // tinyYolov2/depthwiseSeparableConv.ts: pad 1, separableConv2d 'valid' (= 'same'
    // at stride 1), + bias, leaky.
    convs_.push_back(&register_module(name, std::make_unique<SeparableConv3x3>(
                                                device, r, name, channels[i], channels[i + 1], 1)));
  }
  conv8_filters_ = register_parameter(
      "conv8.filters", r.conv(device, "conv8/filters", {1, 1, 512, kOutputChannels}));
  conv8_bias_ = register_parameter("conv8.bias", r.vec(device, "conv8/bias", kOutputChannels));

  r.finish();

  const InputAffine input = mean_rgb_affine(device, kMeanRgb);
  input_scale_ = input.scale_var;
  input_shift_ = input.shift_var;
}

TinyFaceDetector::~TinyFaceDetector() = default;

Var TinyFaceDetector::forward(Tape& t, const Var& x) const {
  const bool ok = x.defined() && x.shape().rank() == 4 && x.shape()[0] >= 1 && x.shape()[1] == 3 &&
                  x.shape()[2] == x.shape()[3] && x.shape()[2] > 0 && x.shape()[2] % 32 == 0;
  if (!ok) {
    throw InvalidArgument(
        "TinyFaceDetector::forward",
        "x has shape " + shape_of(x) +
            ", expected [N, 3, S, S] with S a positive multiple of 32 (RGB 0..255)",
        "pad and resize the image with TinyFaceDetector::preprocess first");
  }
  return body(t, channel_affine(t, x, input_scale_, input_shift_));
}

k::Conv2dParams TinyFaceDetector::conv0_params() {
  k::Conv2dParams p0;
  p0.activation = k::Activation::leaky_relu;
  p0.leaky_slope = kLeakySlope;
  return p0;
}

// runMobilenet with isFirstLayerConv2d: leaky(convLayer(x, conv0, 'valid')),
// then each max pool (written straight into the next depthwise conv's padded
// input in inference) and separable conv, the last pool and conv8.
Var TinyFaceDetector::body(Tape& t, const Var& x) const {
  Var y = conv2d(t, x, conv0_filters_, conv0_bias_, conv0_params(), &conv0_plans_);
  for (const SeparableConv3x3* c : convs_) {
    const k::Pool2d pool = k::pool_same(2, 2, 2, 2, y.shape()[2], y.shape()[3]);
    y = max_pool2d(t, y, pool, c->input_layout(t, k::pool_output_shape(y.shape(), pool)));
    y = c->forward(t, y, k::Activation::leaky_relu, kLeakySlope);
  }
  y = max_pool2d(t, y, k::pool_same(2, 2, 1, 1, y.shape()[2], y.shape()[3]));
  return conv2d(t, y, conv8_filters_, conv8_bias_, k::Conv2dParams{}, &conv8_plans_);
}

Tensor TinyFaceDetector::preprocess(Stream& stream, const Tensor& image, int input_size) const {
  const char* op = "TinyFaceDetector::preprocess";
  require_input_size(input_size, op);
  require_image(image, op);
  const std::int64_t h = image.shape()[2], w = image.shape()[3], side = std::max(h, w);
  const std::int64_t out = input_size;
  if (h == w && side == out) return image;
  // padToSquare(img, isCenterImage = false) puts all the padding after the
  // image, then resizeBilinear(square, out): one pass that reads the taps in
  // the padding as zeros, so the square is never built.
  Tensor y = Tensor::empty(image.device(), Shape{1, 3, out, out});
  k::resize_zero_padded(stream, image, k::ResizeCanvas{side, side, 0, 0},
                        k::ResizeMode::bilinear_legacy, y);
  return y;
}

std::vector<FaceDetection> TinyFaceDetector::detect(Stream& stream, const Tensor& image,
                                                    int input_size, float score_threshold) const {
  const char* op = "TinyFaceDetector::detect";
  require_input_size(input_size, op);
  require_image(image, op);
  if (!(score_threshold > 0.f && score_threshold < 1.f)) {
    throw InvalidArgument(
        op, "score_threshold " + std::to_string(score_threshold) + " is not in (0, 1)",
        "use 0.5 (face-api's default) or another value strictly between 0 and 1");
  }
  const int h = int(image.shape()[2]), w = int(image.shape()[3]);
  Tape tape(stream, /*recording=*/false);
  // Max pools and fused ReLUs can drop a NaN, so the network input is checked:
  // every value the network reads (the pixels the resize read) must be finite.
  // One pass from the image to conv0's input (padded when its plan reads it
  // so): padToSquare (all the padding after the image), resize, normalize,
  // flag non-finite values (no resize, sum, normalize or padding pass of its
  // own).
  const Shape in{1, 3, input_size, input_size};
  const std::int64_t side = std::max(h, w);
  Tensor flag;
  const Var x = resize_normalized(
      tape, image, k::ResizeCanvas{side, side, 0, 0}, in, input_scale_, input_shift_,
      conv0_plans_.input_layout(tape, in, conv0_filters_, conv0_bias_, conv0_params()), flag);
  const Var out = body(tape, x);
  stream.run();
  const float bad = flag.download()[0];
  if (bad != 0) {
    throw InvalidArgument(op, "the image holds NaN or infinite pixels",
                          "pass RGB values in 0..255");
  }
  const std::vector<float> raw = out.value().download();
  const int cells = input_size / 32;
  const auto candidates = decode_tiny_yolo(raw, cells, tiny_yolo_reshaped_size(w, h, input_size),
                                           double(score_threshold));
  std::vector<FaceBox> boxes;
  std::vector<double> scores;
  for (const auto& c : candidates) {
    // NMS runs on the boxes rescaled by input_size (box.rescale(inputSize)).
    boxes.push_back(FaceBox{c.relative.x * input_size, c.relative.y * input_size,
                            c.relative.width * input_size, c.relative.height * input_size});
    scores.push_back(c.score);
  }
  std::vector<FaceDetection> detections;
  for (const std::size_t i : non_max_suppression(boxes, scores, kTinyFaceIouThreshold)) {
    const FaceBox& r = candidates[i].relative;
    detections.push_back(FaceDetection{float(candidates[i].score),
                                       FaceBox{r.x * w, r.y * h, r.width * w, r.height * h}});
  }
  return detections;
}

}  // namespace vkjr2::nets
