#include <vkjr2/nets/face_landmarks.hpp>
#include <vkjr2/nets/separable_conv.hpp>
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

}  // namespace

// ---- input and output mapping -----------------------------------------------------

Var to_landmark_input(Tape& t, const Var& crop) {
  if (!crop.defined() || crop.shape().rank() != 4 || crop.shape()[1] != 3 || crop.numel() == 0) {
    throw InvalidArgument(
        "to_landmark_input",
        "crop has shape " + shape_of(crop) + ", expected a non-empty RGB image batch [N, 3, H, W]",
        "pass face crops as NCHW (extract_face gives [N, 3, h, w])");
  }
  return pad_to_square_and_resize(t, crop, kLandmarkInputSize);
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
          "conv0", std::make_unique<SeparableConv3x3>(device, r, name + "/conv0", cin, cout, 2));
    }
    for (int i = 1; i <= 3; ++i) {
      const std::string n = "conv" + std::to_string(i);
      std::string prefix = name;
      prefix += '/';
      prefix += n;
      convs_[std::size_t(i - 1)] =
          &register_module(n, std::make_unique<SeparableConv3x3>(device, r, prefix, cout, cout, 1));
    }
  }

  // relu(sum) of the block for x; out: the layout of the output's consumer.
  // The running sum goes through the pointwise convs' epilogues (each adds
  // the sum it read as its residual), and each depthwise conv applies the
  // ReLU of the sum as it reads it; in inference each sum is written straight
  // into the next conv's padded input (no padding, add or ReLU pass).
  Var forward(Tape& t, const Var& x, const k::PlaneLayout& out) const {
    const Shape o = output_shape(x.shape());
    const k::PlaneLayout to_conv1 = convs_[0]->input_layout(t, o);
    // face-api sums out1 + (out2 + (out3 + out4)); the running sum below
    // associates left to right instead (differences at float rounding level).
    Var sum = conv0_ != nullptr
                  ? conv0_->forward(t, x, k::Activation::relu, 0.f, {false, Var(), to_conv1})
                  : conv2d(t, x, first_filters_, first_bias_, first_params(x.shape()),
                           &first_plans_, Var(), to_conv1);
    for (std::size_t i = 0; i < convs_.size(); ++i) {
      const bool last = i + 1 == convs_.size();
      SeparableExtras e;
      e.relu_input = i > 0;
      e.residual = sum;
      e.out = last ? out : convs_[i + 1]->input_layout(t, o);
      sum = convs_[i]->forward(t, sum, last ? k::Activation::relu : k::Activation::none, 0.f, e);
    }
    return sum;
  }

  // The block's output shape for x of shape x: conv0's (stride 2, 'same').
  Shape output_shape(const Shape& x) const {
    return conv0_ != nullptr ? conv0_->output_shape(x)
                             : k::conv2d_output_shape(x, first_filters_.shape(), first_params(x));
  }

  // The layout forward() reads x of shape x in with no padding pass.
  k::PlaneLayout input_layout(const Tape& t, const Shape& x) const {
    return conv0_ != nullptr
               ? conv0_->input_layout(t, x)
               : first_plans_.input_layout(t, x, first_filters_, first_bias_, first_params(x));
  }

 private:
  static k::Conv2dParams first_params(const Shape& x) {
    k::Conv2dParams p;
    p.stride_y = p.stride_x = 2;
    p.pad = k::same_padding(x[2], x[3], 3, 3, 2, 2);
    p.activation = k::Activation::relu;
    return p;
  }

  Var first_filters_, first_bias_;
  ConvPlans first_plans_;
  const SeparableConv3x3* conv0_ = nullptr;
  std::array<const SeparableConv3x3*, 3> convs_{};
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

  const InputAffine input = mean_rgb_affine(device, kMeanRgb);
  input_scale_ = input.scale_var;
  input_shift_ = input.shift_var;
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
  return body(t, channel_affine(t, x112, input_scale_, input_shift_));
}

// Four dense blocks (112 → 56 → 28 → 14 → 7), each writing its output in the
// next one's input layout, then avgpool 7×7/2 valid → [N, 256] → fc.
Var FaceLandmark68Net::body(Tape& t, const Var& x) const {
  Var y = x;
  for (std::size_t i = 0; i < blocks_.size(); ++i) {
    const Shape os = blocks_[i]->output_shape(y.shape());
    const k::PlaneLayout out =
        i + 1 < blocks_.size() ? blocks_[i + 1]->input_layout(t, os) : k::PlaneLayout{};
    y = blocks_[i]->forward(t, y, out);
  }
  y = avg_pool2d(t, y, k::pool_valid(7, 7, 2, 2));  // [N, 256, 1, 1]
  y = reshape(t, y, Shape{y.shape()[0], y.shape()[1]});
  return linear(t, y, fc_weights_, fc_bias_);
}

std::array<float, FaceLandmark68Net::kOutputs> FaceLandmark68Net::relative_landmarks(
    Stream& stream, const Tensor& crop) const {
  Tape tape(stream, /*recording=*/false);
  // ReLU maps NaN to 0, so the network input is checked (as the detector
  // does): every value of the 112² input (the crop pixels the resize read)
  // must be finite.
  // One pass from the crop to conv0's input (padded when its plan reads it
  // so): pad to square, resize, normalize, flag non-finite values (no
  // resize, normalize, padding or sum pass of its own).
  const Shape in{crop.shape()[0], 3, kLandmarkInputSize, kLandmarkInputSize};
  Tensor flag;
  const Var x =
      resize_normalized(tape, crop, square_canvas(crop.shape()[2], crop.shape()[3]), in,
                        input_scale_, input_shift_, blocks_[0]->input_layout(tape, in), flag);
  const Var raw = body(tape, x);
  stream.run();
  const float bad = flag.download()[0];
  if (bad != 0) {
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
