#include <vkjr2/nets/face_landmarks.hpp>
#include <vkjr2/nets/tfjs_weights.hpp>
#include <vkjr2/runtime/error.hpp>

#include <algorithm>
#include <cmath>
#include <set>
#include <string>

namespace vkjr2::nets {
namespace {

namespace k = kernels;

// FaceFeatureExtractor.forwardInput: normalize(x, meanRgb).div(255).
constexpr std::array<float, 3> kMeanRgb = {122.782f, 117.001f, 104.298f};

std::string shape_of(const Var& x) {
  return x.defined() ? x.shape().str() : std::string("(undefined)");
}
std::string shape_of(const Tensor& x) {
  return x.defined() ? x.shape().str() : std::string("(undefined)");
}

// One RGB face crop [1, 3, h, w] with h, w ≥ 1.
void require_crop(const Tensor& crop, const char* op, const char* name) {
  const bool ok = crop.defined() && crop.shape().rank() == 4 && crop.shape()[0] == 1 &&
                  crop.shape()[1] == 3 && crop.numel() > 0 && crop.dtype() == DType::f32;
  if (!ok) {
    throw InvalidArgument(op,
                          std::string(name) + " has shape " + shape_of(crop) +
                              ", expected one non-empty f32 RGB image [1, 3, H, W]",
                          "pass one image (image_to_device gives [1, 3, H, W], RGB 0..255)");
  }
}

// TF "same" padding of a 3×3 window at `stride` over x's spatial size.
k::Padding2d same3(const Var& x, int stride) {
  return k::same_padding(x.shape()[2], x.shape()[3], 3, 3, stride, stride);
}

}  // namespace

// ---- input and output mapping -----------------------------------------------------

Var to_landmark_input(Tape& t, const Var& crop) {
  if (!crop.defined() || crop.shape().rank() != 4 || crop.shape()[1] != 3 || crop.numel() == 0) {
    throw InvalidArgument(
        "to_landmark_input",
        "crop has shape " + shape_of(crop) + ", expected a non-empty RGB image batch [N, 3, H, W]",
        "pass face crops as NCHW (extract_face gives [N, 3, h, w])");
  }
  const std::int64_t h = crop.shape()[2], w = crop.shape()[3];
  Var square = crop;
  if (h != w) {  // padToSquare(img, isCenterImage = true)
    const std::int64_t diff = std::abs(h - w);
    const auto after = std::int32_t(js_round_half(diff));
    const auto before = std::int32_t(diff - after);
    k::Pad2d p;
    if (h > w) {
      p.left = before;
      p.right = after;
    } else {
      p.top = before;
      p.bottom = after;
    }
    square = pad(t, crop, p, 0.f);
  }
  if (std::max(h, w) == kLandmarkInputSize) return square;
  return resize(t, square, k::ResizeMode::bilinear_legacy, kLandmarkInputSize, kLandmarkInputSize);
}

std::array<float, 2 * kLandmarkCount> landmarks_relative_to_crop(const float* raw, double crop_w,
                                                                 double crop_h) {
  if (!(crop_w > 0) || !(crop_h > 0) || !std::isfinite(crop_w) || !std::isfinite(crop_h)) {
    throw InvalidArgument(
        "landmarks_relative_to_crop",
        "crop size " + std::to_string(crop_w) + "×" + std::to_string(crop_h) + " is not positive",
        "pass the width and height of the crop the landmarks were computed on");
  }
  // postProcess: JS doubles for the dimensions, float32 tensors for the rest.
  const double scale = double(kLandmarkInputSize) / std::max(crop_h, crop_w);
  const double width = crop_w * scale, height = crop_h * scale;
  const auto pad_x = float(width < height ? std::abs(width - height) / 2 : 0.0);
  const auto pad_y = float(height < width ? std::abs(width - height) / 2 : 0.0);
  const auto size = float(kLandmarkInputSize);
  std::array<float, 2 * kLandmarkCount> rel{};
  for (std::size_t i = 0; i < rel.size(); i += 2) {
    rel[i] = (raw[i] * size - pad_x) / float(width);
    rel[i + 1] = (raw[i + 1] * size - pad_y) / float(height);
  }
  return rel;
}

// ---- the network -------------------------------------------------------------------

// depthwiseSeparableConv (common/): separableConv2d(x, dw, pw, stride, 'same') + bias,
// the depthwise step carrying the stride and TF's asymmetric "same" padding.
class FaceLandmark68Net::SeparableConv : public Module {
 public:
  SeparableConv(const Device& device, WeightReader& r, const std::string& prefix, std::int64_t cin,
                std::int64_t cout, int stride)
      : stride_(stride) {
    depthwise_ = register_parameter("depthwise_filter",
                                    r.depthwise(device, prefix + "/depthwise_filter", cin));
    pointwise_ = register_parameter(
        "pointwise_filter", r.conv(device, prefix + "/pointwise_filter", {1, 1, cin, cout}));
    bias_ = register_parameter("bias", r.vec(device, prefix + "/bias", cout));
    groups_ = int(cin);
  }

  Var forward(Tape& t, const Var& x, k::Activation act) const {
    k::Conv2dParams dw;
    dw.stride_y = dw.stride_x = stride_;
    dw.pad = same3(x, stride_);
    dw.groups = groups_;
    const Var mid = conv2d(t, x, depthwise_, Var(), dw);
    k::Conv2dParams pw;
    pw.activation = act;
    return conv2d(t, mid, pointwise_, bias_, pw, &pointwise_packed_);
  }

  // Packs the pointwise filter for the fast conv (again only if it changes).
  void pack(Stream& s) const { pointwise_packed_.get(s, pointwise_); }

 private:
  Var depthwise_, pointwise_, bias_;
  ConvWeightCache pointwise_packed_;
  int stride_, groups_ = 1;
};

// denseBlock4 (faceFeatureExtractor/denseBlock.ts): out1 = relu(conv0(x)) at
// stride 2, then three separable convs whose inputs are relu of the running
// sum of the previous outputs; the block returns relu of the full sum.
class FaceLandmark68Net::DenseBlock : public Module {
 public:
  DenseBlock(const Device& device, WeightReader& r, const std::string& name, std::int64_t cin,
             std::int64_t cout, bool first) {
    if (first) {
      first_filters_ = register_parameter(
          "conv0.filters", r.conv(device, name + "/conv0/filters", {3, 3, cin, cout}));
      first_bias_ = register_parameter("conv0.bias", r.vec(device, name + "/conv0/bias", cout));
    } else {
      conv0_ = &register_module(
          "conv0", std::make_unique<SeparableConv>(device, r, name + "/conv0", cin, cout, 2));
    }
    for (int i = 1; i <= 3; ++i) {
      const std::string n = "conv" + std::to_string(i);
      std::string prefix = name;
      prefix += '/';
      prefix += n;
      convs_[std::size_t(i - 1)] =
          &register_module(n, std::make_unique<SeparableConv>(device, r, prefix, cout, cout, 1));
    }
  }

  Var forward(Tape& t, const Var& x) const {
    Var out1;
    if (conv0_ != nullptr) {
      out1 = conv0_->forward(t, x, k::Activation::relu);
    } else {  // tf.conv2d(x, filters, [2, 2], 'same') + bias, relu
      k::Conv2dParams p;
      p.stride_y = p.stride_x = 2;
      p.pad = same3(x, 2);
      p.activation = k::Activation::relu;
      out1 = conv2d(t, x, first_filters_, first_bias_, p, &first_packed_);
    }
    // face-api sums out1 + (out2 + (out3 + out4)); the running sum below
    // associates left to right instead (differences at float rounding level).
    Var sum = out1;
    for (std::size_t i = 0; i < convs_.size(); ++i) {
      const Var in = i == 0 ? out1 : relu(t, sum);
      sum = add(t, sum, convs_[i]->forward(t, in, k::Activation::none));
    }
    return relu(t, sum);
  }

  void pack(Stream& s) const {
    if (conv0_ != nullptr) {
      conv0_->pack(s);
    } else {
      first_packed_.get(s, first_filters_);
    }
    for (const SeparableConv* c : convs_) c->pack(s);
  }

 private:
  Var first_filters_, first_bias_;
  ConvWeightCache first_packed_;
  const SeparableConv* conv0_ = nullptr;
  std::array<const SeparableConv*, 3> convs_{};
};

std::unique_ptr<FaceLandmark68Net> FaceLandmark68Net::load(const Device& device,
                                                           const std::filesystem::path& manifest) {
  return std::make_unique<FaceLandmark68Net>(device, load_tfjs_weights(manifest));
}

FaceLandmark68Net::FaceLandmark68Net(const Device& device, const TfjsWeights& weights) {
  WeightReader r(weights, "FaceLandmark68Net", "face_landmark_68_model");
  constexpr std::array<std::int64_t, 5> channels = {3, 32, 64, 128, 256};
  for (std::size_t i = 0; i < 4; ++i) {
    const std::string name = "dense" + std::to_string(i);
    blocks_.push_back(&register_module(
        name, std::make_unique<DenseBlock>(device, r, name, channels[i], channels[i + 1], i == 0)));
  }
  fc_weights_ = register_parameter(
      "fc.weights",
      Tensor::from(device, Shape{256, kOutputs}, r.take("fc/weights", {256, kOutputs}).values));
  fc_bias_ = register_parameter("fc.bias", r.vec(device, "fc/bias", kOutputs));

  r.finish();

  std::vector<float> scale(3, 1.f / 255.f), shift(3);
  for (std::size_t c = 0; c < 3; ++c) shift[c] = -kMeanRgb[c] / 255.f;
  input_scale_ = Var(Tensor::from(device, Shape{3}, scale));
  input_shift_ = Var(Tensor::from(device, Shape{3}, shift));

  // Conv weights packed once at load (repacked only if a weight changes).
  Stream stream(device);
  for (const DenseBlock* block : blocks_) block->pack(stream);
  stream.run();
}

FaceLandmark68Net::~FaceLandmark68Net() = default;

Var FaceLandmark68Net::forward(Tape& t, const Var& x112) const {
  const bool ok = x112.defined() && x112.shape().rank() == 4 && x112.shape()[0] >= 1 &&
                  x112.shape()[1] == 3 && x112.shape()[2] == kLandmarkInputSize &&
                  x112.shape()[3] == kLandmarkInputSize;
  if (!ok) {
    throw InvalidArgument(
        "FaceLandmark68Net::forward",
        "x112 has shape " + shape_of(x112) + ", expected [N, 3, 112, 112] (RGB 0..255)",
        "pad and resize face crops with to_landmark_input first");
  }
  Var x = channel_affine(t, x112, input_scale_, input_shift_);
  for (const DenseBlock* block : blocks_) x = block->forward(t, x);  // 112 → 56 → 28 → 14 → 7
  x = avg_pool2d(t, x, k::pool_valid(7, 7, 2, 2));                   // [N, 256, 1, 1]
  x = reshape(t, x, Shape{x.shape()[0], x.shape()[1]});
  return linear(t, x, fc_weights_, fc_bias_);
}

std::array<float, FaceLandmark68Net::kOutputs> FaceLandmark68Net::relative_landmarks(
    Stream& stream, const Tensor& crop) const {
  Tape tape(stream, /*recording=*/false);
  // ReLU maps NaN to 0, so the crop itself is checked: its sum is finite iff
  // every pixel is (for pixel values in any sane range).
  const Var total = sum_all(tape, Var(crop));
  const Var raw = forward(tape, to_landmark_input(tape, Var(crop)));
  stream.run();
  if (!std::isfinite(total.value().download()[0])) {
    throw InvalidArgument("FaceLandmark68Net", "the face crop holds NaN or infinite pixels",
                          "pass RGB values in 0..255");
  }
  const std::vector<float> values = raw.value().download();
  return landmarks_relative_to_crop(values.data(), double(crop.shape()[3]),
                                    double(crop.shape()[2]));
}

std::vector<float> FaceLandmark68Net::detect_landmarks(Stream& stream,
                                                       const Tensor& face_crop_nchw) const {
  require_crop(face_crop_nchw, "FaceLandmark68Net::detect_landmarks", "face_crop_nchw");
  const auto rel = relative_landmarks(stream, face_crop_nchw);
  const auto w = float(face_crop_nchw.shape()[3]), h = float(face_crop_nchw.shape()[2]);
  std::vector<float> xy(rel.size());
  for (std::size_t i = 0; i < rel.size(); i += 2) {
    xy[i] = rel[i] * w;
    xy[i + 1] = rel[i + 1] * h;
  }
  return xy;
}

std::vector<double> FaceLandmark68Net::landmarks_in_image(Stream& stream, const Tensor& image,
                                                          const FaceBox& box) const {
  require_crop(image, "FaceLandmark68Net::landmarks_in_image", "image_nchw");
  Tensor crop;
  {
    Tape tape(stream, /*recording=*/false);
    crop = extract_face(tape, Var(image), box).value();  // clips + floors like face-api
  }
  const auto rel = relative_landmarks(stream, crop);
  const auto w = double(crop.shape()[3]), h = double(crop.shape()[2]);
  std::vector<double> xy(rel.size());
  for (std::size_t i = 0; i < rel.size(); i += 2) {  // FaceLandmarks: rel·crop size + box origin
    xy[i] = double(rel[i]) * w + box.x;
    xy[i + 1] = double(rel[i + 1]) * h + box.y;
  }
  return xy;
}

}  // namespace vkjr2::nets
