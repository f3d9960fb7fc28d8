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

  Var forward(Tape& t, const Var& x) const {
    Var out1;
    if (conv0_ != nullptr) {
      out1 = conv0_->forward(t, x, k::Activation::relu);
    } else {  // tf.conv2d(x, filters, [2, 2], 'same') + bias, relu
      out1 = conv2d(t, x, first_filters_, first_bias_, first_params(x.shape()), &first_packed_);
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
    for (const SeparableConv3x3* c : convs_) c->pack(s);
  }

  // The block's output shape for x of shape x: conv0's (stride 2, 'same').
  Shape output_shape(const Shape& x) const {
    return conv0_ != nullptr ? conv0_->output_shape(x)
                             : k::conv2d_output_shape(x, first_filters_.shape(), first_params(x));
  }

  // Whether forward_inference can run this block for x of shape x (no
  // parameter needs a gradient, every conv runs a variant with padded io).
  bool infers(const Tape& t, const Shape& x) const {
    const Shape o = output_shape(x);
    const bool first = conv0_ != nullptr
                           ? conv0_->infers(t, x)
                           : !t.needs_grad({&first_filters_, &first_bias_}) &&
                                 k::conv2d_select(t.device(), x, first_filters_.shape(),
                                                  first_params(x)) == k::Conv2dAlgo::blocked;
    return first && std::all_of(convs_.begin(), convs_.end(),
                                [&](const SeparableConv3x3* c) { return c->infers(t, o); });
  }

  // conv0's zero-padded input for x of shape x, for the previous block to
  // write its output into (the first block: for the normalized image; see
  // FaceLandmark68Net::relative_landmarks).
  k::Conv2dPadded padded_input(Tape& t, const Shape& x) const {
    return conv0_ != nullptr
               ? conv0_->padded_input(t, x)
               : k::conv2d_padded_input(t.stream(), x, first_filters_.shape(), first_params(x));
  }

  // Inference (infers()): the block with the running sum kept in the
  // separable convs' padded input layout, two tensors used in turn. Each
  // pointwise conv adds the sum in its epilogue and writes the new one
  // straight into the next depthwise conv's padded input, which applies the
  // ReLU as it reads it; the last one applies the block's ReLU itself. So no
  // padding, add or ReLU pass runs. x: plain (the first block only) or xp,
  // its padded copy (already ReLU'd); the result goes into `into` (the next
  // block's padded input; then undefined) or is returned.
  Var forward_inference(Tape& t, const Var& x, const k::Conv2dPadded& xp,
                        const k::Conv2dPadded* into) const {
    const Shape in = xp.defined() ? xp.shape : x.shape();
    const Shape o = output_shape(in);
    const std::array<k::Conv2dPadded, 2> sums = {convs_[0]->padded_input(t, o),
                                                 convs_[0]->padded_input(t, o)};
    if (conv0_ != nullptr) {
      conv0_->run_padded(t, xp, false, k::Activation::relu, 0.f, nullptr, &sums[0]);
    } else {
      k::Conv2dPaddedIo io;
      io.y = &sums[0];
      if (xp.defined()) io.x = &xp;
      k::conv2d_padded(t.stream(), xp.defined() ? nullptr : &x.value(), first_filters_.value(),
                       &first_bias_.value(), nullptr, first_params(in), io,
                       &first_packed_.get(t.stream(), first_filters_));
    }
    convs_[0]->run_padded(t, sums[0], false, k::Activation::none, 0.f, &sums[0], &sums[1]);
    convs_[1]->run_padded(t, sums[1], true, k::Activation::none, 0.f, &sums[1], &sums[0]);
    return convs_[2]->run_padded(t, sums[0], true, k::Activation::relu, 0.f, &sums[0], into);
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
  ConvWeightCache first_packed_;
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
  if (infers(t, x112.shape(), t.needs_grad({&x112}))) {
    return forward_inference(t, x, k::Conv2dPadded{});
  }
  for (const DenseBlock* block : blocks_) x = block->forward(t, x);  // 112 → 56 → 28 → 14 → 7
  return head(t, x);
}

bool FaceLandmark68Net::infers(const Tape& t, const Shape& x112, bool input_needs_grad) const {
  bool infers = !input_needs_grad;
  Shape xs = x112;
  for (const DenseBlock* block : blocks_) {
    infers = infers && block->infers(t, xs);
    xs = block->output_shape(xs);
  }
  return infers;
}

// Inference (infers()): each block writes its output straight into the next
// one's padded input (DenseBlock::forward_inference). The normalized input:
// x, or its padded copy x0p (then x is not read).
Var FaceLandmark68Net::forward_inference(Tape& t, const Var& x, const k::Conv2dPadded& x0p) const {
  k::Conv2dPadded xp = x0p;
  Shape xs = x0p.defined() ? x0p.shape : x.shape();
  Var y;
  for (std::size_t i = 0; i < blocks_.size(); ++i) {
    const Shape os = blocks_[i]->output_shape(xs);
    const k::Conv2dPadded into =
        i + 1 < blocks_.size() ? blocks_[i + 1]->padded_input(t, os) : k::Conv2dPadded{};
    y = blocks_[i]->forward_inference(t, x, xp, into.defined() ? &into : nullptr);
    xp = into;
    xs = os;
  }
  return head(t, y);
}

// avgpool 7×7/2 valid → [N, 256] → fc.
Var FaceLandmark68Net::head(Tape& t, const Var& x7) const {
  Var x = avg_pool2d(t, x7, k::pool_valid(7, 7, 2, 2));  // [N, 256, 1, 1]
  x = reshape(t, x, Shape{x.shape()[0], x.shape()[1]});
  return linear(t, x, fc_weights_, fc_bias_);
}

std::array<float, FaceLandmark68Net::kOutputs> FaceLandmark68Net::relative_landmarks(
    Stream& stream, const Tensor& crop) const {
  Tape tape(stream, /*recording=*/false);
  // ReLU maps NaN to 0, so the network input is checked (as the detector
  // does): every value of the 112² input (the crop pixels the resize read)
  // must be finite.
  const Shape in{crop.shape()[0], 3, kLandmarkInputSize, kLandmarkInputSize};
  Var raw;
  float bad = 0;
  if (infers(tape, in, false)) {
    // One pass from the crop to conv0's padded input: pad to square, resize,
    // normalize, flag non-finite values (no resize, normalize, padding or
    // sum pass of its own).
    const k::Conv2dPadded x0p = blocks_[0]->padded_input(tape, in);
    const Tensor flag =
        resize_normalized_into(stream, crop, square_canvas(crop.shape()[2], crop.shape()[3]),
                               input_scale_, input_shift_, x0p);
    raw = forward_inference(tape, Var(), x0p);
    stream.run();
    bad = flag.download()[0];
  } else {
    const Var input = to_landmark_input(tape, Var(crop));
    const Var total = sum_all(tape, input);  // finite iff every value is (for sane ranges)
    raw = forward(tape, input);
    stream.run();
    bad = std::isfinite(total.value().download()[0]) ? 0.f : 1.f;
  }
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
