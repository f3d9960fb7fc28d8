#include <vkjr2/kernels/elementwise.hpp>
#include <vkjr2/kernels/layout.hpp>
#include <vkjr2/kernels/matmul.hpp>
#include <vkjr2/kernels/pool.hpp>
#include <vkjr2/nets/face_recognition.hpp>
#include <vkjr2/nets/tfjs_weights.hpp>
#include <vkjr2/runtime/error.hpp>

#include <algorithm>
#include <array>
#include <cmath>
#include <set>
#include <span>
#include <string>

namespace vkjr2::nets {
namespace {

namespace k = kernels;

constexpr std::array<float, 3> kMeanRgb = {122.782f, 117.001f, 104.298f};

void require_image(const Var& x, const char* op, const char* name) {
  if (!x.defined() || x.shape().rank() != 4 || x.numel() == 0) {
    throw InvalidArgument(op,
                          std::string(name) + " has shape " +
                              (x.defined() ? x.shape().str() : std::string("(undefined)")) +
                              ", expected a non-empty NCHW image [N, C, H, W]",
                          "pass a 4-D tensor (image_to_device gives [1, C, H, W])");
  }
}

}  // namespace

// ---- pad, resize ------------------------------------------------------------

Var to_recognition_input(Tape& t, const Var& chip) {
  require_image(chip, "to_recognition_input", "chip");
  return pad_to_square_and_resize(t, chip, kRecognitionInputSize);
}

Tensor to_recognition_input(Stream& stream, const Tensor& chip) {
  Tape tape(stream, /*recording=*/false);
  return to_recognition_input(tape, Var(chip)).value();
}

// ---- the network -------------------------------------------------------------------

// conv + bias, then the scale layer x·w + b, then optionally ReLU (convLayer.ts).
// Where no parameter needs a gradient (inference, a frozen embedder) the scale
// layer is folded into the conv — w'[co] = w[co]·s[co], b' = b·s + t — with
// the ReLU fused, and w' packed once: one dispatch instead of three. The folded
// weights are rebuilt when a parameter's version changes (an optimizer step).
class FaceRecognitionNet::ConvLayer : public Module {
 public:
  ConvLayer(const Device& device, WeightReader& r, const std::string& prefix, int kernel,
            std::int64_t cin, std::int64_t cout, bool down)
      : down_(down) {
    const std::string tf = prefix + "/";
    filters_ = register_parameter(
        "conv.filters",
        conv_weight_from_hwio(device, r.take(tf + "conv/filters", {kernel, kernel, cin, cout}),
                              (tf + "conv/filters").c_str()));
    bias_ = register_parameter("conv.bias", vector_from(device, r.take(tf + "conv/bias", {cout}),
                                                        cout, (tf + "conv/bias").c_str()));
    scale_ = register_parameter("scale.weights",
                                vector_from(device, r.take(tf + "scale/weights", {cout}), cout,
                                            (tf + "scale/weights").c_str()));
    shift_ =
        register_parameter("scale.biases", vector_from(device, r.take(tf + "scale/biases", {cout}),
                                                       cout, (tf + "scale/biases").c_str()));
    kernel_ = kernel;
  }

  // Folds the input normalization x·scale + shift (per input channel) into
  // the folded weights too; forward() then takes the raw input when it folds
  // (and the caller applies the normalization itself when it does not).
  // Exact for this 'valid' conv (no zero taps): conv(x·s + t) = conv_{w·s}(x)
  // + Σ_{ci,ky,kx} w·t.
  void fold_input_affine(const Device& device, std::span<const float> scale,
                         std::span<const float> shift) {
    const Shape& ws = filters_.shape();
    if (!down_ || std::int64_t(scale.size()) != ws[1] || std::int64_t(shift.size()) != ws[1]) {
      throw Error("FaceRecognitionNet",
                  "an input affine folded into a padded conv or of " +
                      std::to_string(scale.size()) + " channels",
                  "fold it into the 'valid' first conv only");
    }
    in_scale_ = Tensor::from(device, Shape{ws[1]}, std::vector<float>(scale.begin(), scale.end()));
    std::vector<float> taps(std::size_t(ws[1] * ws[2] * ws[3]));
    for (std::size_t i = 0; i < taps.size(); ++i) taps[i] = shift[i / std::size_t(ws[2] * ws[3])];
    in_shift_taps_ = Tensor::from(device, Shape{ws[1] * ws[2] * ws[3], 1}, taps);
    folded_filters_ = Var();  // refold
  }

  // Whether forward() folds the scale layer (no parameter needs a gradient):
  // only then can it take a residual.
  bool folds(const Tape& t) const { return !t.needs_grad({&filters_, &bias_, &scale_, &shift_}); }

  // act(scale(conv(x)) + residual); residual (folded only, see folds()):
  // [N, Cr <= Cout, Hout, Wout], added in the conv's epilogue. out: the
  // layout of the output's consumer (ConvPlans::input_layout).
  Var forward(Tape& t, const Var& x, bool with_relu, const Var& residual = Var(),
              const k::PlaneLayout& out = {}) const {
    k::Conv2dParams p = params(x.shape(), with_relu);
    if (folds(t)) {
      fold(t.stream());
      return conv2d(t, x, folded_filters_, folded_bias_, p, &folded_plans_, residual, out);
    }
    p.activation = k::Activation::none;
    if (residual.defined()) {
      throw Error("FaceRecognitionNet", "a residual passed to an unfolded conv layer",
                  "add the residual after the scale layer (see ConvLayer::folds)");
    }
    Var y = conv2d(t, x, filters_, bias_, p);
    y = channel_affine(t, y, scale_, shift_);
    return with_relu ? relu(t, y) : y;
  }

  // The layout forward() reads x of shape x in with no padding pass (plain
  // unless the layer folds).
  k::PlaneLayout input_layout(const Tape& t, const Shape& x) const {
    if (!folds(t)) return {};
    fold(t.stream());
    return folded_plans_.input_layout(t, x, folded_filters_, folded_bias_, params(x, true));
  }

  // The conv's parameters for input x (activation: the folded form's).
  k::Conv2dParams params(const Shape& x, bool with_relu) const {
    k::Conv2dParams p;
    if (down_) {  // convDown: stride 2, 'valid'
      p.stride_y = p.stride_x = 2;
    } else {  // conv / convNoRelu: stride 1, 'same'
      p.pad = k::same_padding(x[2], x[3], kernel_, kernel_, 1, 1);
    }
    p.activation = with_relu ? k::Activation::relu : k::Activation::none;
    return p;
  }
  Shape weight_shape() const { return filters_.shape(); }

  // Records the folding on `stream` unless the folded weights are up to date.
  void fold(Stream& stream) const {
    const std::array<std::uint64_t, 4> versions = {filters_.version(), bias_.version(),
                                                   scale_.version(), shift_.version()};
    if (folded_filters_.defined() && versions == folded_versions_) return;
    const Tensor& w = filters_.value();
    const Shape& ws = w.shape();
    const Shape rows{1, ws[0], ws[1] * ws[2], ws[3]};  // one channel per output channel
    Tensor fw = Tensor::empty(stream.device(), ws);
    k::mul_channel(stream, w.reshape(rows), scale_.value(), fw.reshape(rows));
    const Shape column{1, ws[0], 1, 1};
    Tensor fb = Tensor::empty(stream.device(), Shape{ws[0]});
    k::channel_affine(stream, bias_.value().reshape(column), scale_.value(), shift_.value(),
                      fb.reshape(column));
    if (in_scale_.defined()) {  // see fold_input_affine
      Tensor taps_sum = Tensor::empty(stream.device(), Shape{ws[0], 1});
      k::matmul(stream, fw.reshape(Shape{ws[0], ws[1] * ws[2] * ws[3]}), in_shift_taps_, taps_sum);
      Tensor fb_in = Tensor::empty(stream.device(), Shape{ws[0]});
      k::add(stream, fb, taps_sum.reshape(Shape{ws[0]}), fb_in);
      Tensor fw_in = Tensor::empty(stream.device(), ws);
      k::mul_channel(stream, fw, in_scale_, fw_in);  // OIHW: the input channel is dim 1
      fw = fw_in;
      fb = fb_in;
    }
    folded_filters_ = Var(fw);
    folded_bias_ = Var(fb);
    folded_versions_ = versions;
  }

 private:
  Var filters_, bias_, scale_, shift_;
  Tensor in_scale_, in_shift_taps_;  // fold_input_affine: [Cin] and [Cin·KH·KW, 1]
  mutable Var folded_filters_, folded_bias_;
  mutable std::array<std::uint64_t, 4> folded_versions_{};
  ConvPlans folded_plans_;
  int kernel_ = 3;
  bool down_;
};

// residual / residualDown (residualLayer.ts).
class FaceRecognitionNet::Residual : public Module {
 public:
  Residual(const Device& device, WeightReader& r, const std::string& name, std::int64_t cin,
           std::int64_t cout, bool down)
      : down_(down) {
    conv1_ = &register_module(
        "conv1", std::make_unique<ConvLayer>(device, r, name + "/conv1", 3, cin, cout, down));
    conv2_ = &register_module(
        "conv2", std::make_unique<ConvLayer>(device, r, name + "/conv2", 3, cout, cout, false));
  }

  // relu(conv2(conv1(x)) + shortcut); out: the layout of the output's
  // consumer. When conv2 folds its scale layer the add and the ReLU run in
  // its epilogue; the down blocks' shortcut (x average-pooled, its channels
  // zero-padded) goes in without the zero channels (the conv adds none past
  // the residual's channels), unless the branch needs the zero row and
  // column (3×3 vs 4×4, 1×1 vs 2×2). In inference conv1 writes straight into
  // conv2's padded input, and a non-down block's padded input is conv2's
  // shortcut as it is (the same layout).
  Var forward(Tape& t, const Var& x, const k::PlaneLayout& out) const {
    const bool fuse = conv2_->folds(t);
    Var shortcut = x;
    if (down_) shortcut = avg_pool2d(t, x, k::pool_valid(2, 2, 2, 2));
    const Shape mid = mid_shape(x.shape());
    const bool shortcut_fits = !down_ || fits(shortcut.shape(), mid);
    if (fuse && shortcut_fits) {
      const Var y = conv1_->forward(t, x, true, Var(), conv2_->input_layout(t, mid));
      return conv2_->forward(t, y, true, shortcut, out);
    }
    Var y = conv2_->forward(t, conv1_->forward(t, x, true), false);
    if (!down_) return relu(t, add(t, y, shortcut));
    const Shape& ps = shortcut.shape();
    if (ps[2] != y.shape()[2] || ps[3] != y.shape()[3]) {
      // One zero row at the bottom, then one zero column at the right.
      y = pad(t, y, k::Pad2d{0, 1, 0, 1}, 0.f);
    }
    if (ps[1] != y.shape()[1]) {
      // Channels doubled by appending zeros to the shortcut.
      Tensor zeros = Tensor::empty(t.device(), ps);
      t.stream().fill(zeros, 0.f);
      const std::array<Var, 2> parts = {shortcut, Var(zeros)};
      shortcut = concat_channels(t, parts);
    }
    if (!(shortcut.shape() == y.shape())) {
      throw Error("FaceRecognitionNet",
                  "residual shortcut " + shortcut.shape().str() + " does not match branch " +
                      y.shape().str(),
                  "the input must be 150×150 (use to_recognition_input)");
    }
    return relu(t, add(t, shortcut, y));
  }

  void fold(Stream& stream) const {
    conv1_->fold(stream);
    conv2_->fold(stream);
  }

  // conv1's output shape (conv2's input and output) for x of shape x.
  Shape mid_shape(const Shape& x) const {
    return k::conv2d_output_shape(x, conv1_->weight_shape(), conv1_->params(x, true));
  }
  Shape output_shape(const Shape& x) const { return down_ ? mid_shape(x) : x; }

  // The layout forward() reads x of shape x in with no padding pass: conv1's
  // (plain for the down blocks: their input also feeds the average pool).
  k::PlaneLayout input_layout(const Tape& t, const Shape& x) const {
    return down_ ? k::PlaneLayout{} : conv1_->input_layout(t, x);
  }

 private:
  // The pooled shortcut goes into conv2's epilogue: same size, no more channels.
  static bool fits(const Shape& pooled, const Shape& mid) {
    return pooled[2] == mid[2] && pooled[3] == mid[3] && pooled[1] <= mid[1];
  }

  ConvLayer* conv1_;
  ConvLayer* conv2_;
  bool down_;
};

std::unique_ptr<FaceRecognitionNet> FaceRecognitionNet::load(
    const Device& device, const std::filesystem::path& manifest) {
  return std::make_unique<FaceRecognitionNet>(device, load_tfjs_weights(manifest));
}

FaceRecognitionNet::FaceRecognitionNet(const Device& device, const TfjsWeights& weights) {
  WeightReader r(weights, "FaceRecognitionNet", "face_recognition_model");
  conv32_down_ = &register_module(
      "conv32_down", std::make_unique<ConvLayer>(device, r, "conv32_down", 7, 3, 32, true));
  struct BlockSpec {
    const char* name;
    std::int64_t cin, cout;
    bool down;
  };
  constexpr std::array<BlockSpec, 14> specs = {{
      {"conv32_1", 32, 32, false},
      {"conv32_2", 32, 32, false},
      {"conv32_3", 32, 32, false},
      {"conv64_down", 32, 64, true},
      {"conv64_1", 64, 64, false},
      {"conv64_2", 64, 64, false},
      {"conv64_3", 64, 64, false},
      {"conv128_down", 64, 128, true},
      {"conv128_1", 128, 128, false},
      {"conv128_2", 128, 128, false},
      {"conv256_down", 128, 256, true},
      {"conv256_1", 256, 256, false},
      {"conv256_2", 256, 256, false},
      {"conv256_down_out", 256, 256, true},
  }};
  for (const BlockSpec& b : specs) {
    blocks_.push_back(&register_module(
        b.name, std::make_unique<Residual>(device, r, b.name, b.cin, b.cout, b.down)));
  }
  const HostTensor& fc = r.take("fc", {256, kDescriptorSize});
  fc_ = register_parameter("fc", Tensor::from(device, Shape{256, kDescriptorSize}, fc.values));

  r.finish();

  const InputAffine input = mean_rgb_affine(device, kMeanRgb);
  input_scale_ = input.scale_var;
  input_shift_ = input.shift_var;
  conv32_down_->fold_input_affine(device, input.scale, input.shift);

  // The scale layers folded into the convs once at load (again only after a
  // parameter changed).
  Stream stream(device);
  conv32_down_->fold(stream);
  for (const Residual* block : blocks_) block->fold(stream);
  stream.run();
}

FaceRecognitionNet::~FaceRecognitionNet() = default;

void FaceRecognitionNet::set_frozen(bool frozen) const {
  for (const Var& p : parameters()) p.set_requires_grad(!frozen);
}

Tensor FaceRecognitionNet::describe(Stream& stream, const Tensor& rgb) const {
  Tape tape(stream, /*recording=*/false);
  return forward(tape, Var(rgb)).value();
}

Var FaceRecognitionNet::forward(Tape& t, const Var& rgb) const {
  const bool ok = rgb.defined() && rgb.shape().rank() == 4 && rgb.shape()[0] >= 1 &&
                  rgb.shape()[1] == 3 && rgb.shape()[2] == kRecognitionInputSize &&
                  rgb.shape()[3] == kRecognitionInputSize;
  if (!ok) {
    throw InvalidArgument(
        "FaceRecognitionNet::forward",
        "rgb has shape " + (rgb.defined() ? rgb.shape().str() : std::string("(undefined)")) +
            ", expected [N, 3, 150, 150] (RGB 0..255)",
        "crop the face and resize it with to_recognition_input (pads to a square, then 150×150)");
  }
  // normalize(x, meanRgb) / 255 (FaceRecognitionNet.ts).
  // The normalization is folded into conv32_down's folded weights.
  Var x = conv32_down_->folds(t) ? rgb : channel_affine(t, rgb, input_scale_, input_shift_);
  x = conv32_down_->forward(t, x, true);
  // Inference: the max pool and each block write their output straight into
  // the next block's padded conv1 input (a down block takes it plain).
  const k::Pool2d pool = k::pool_valid(3, 3, 2, 2);
  x = max_pool2d(t, x, pool,
                 blocks_.front()->input_layout(t, k::pool_output_shape(x.shape(), pool)));
  for (std::size_t i = 0; i < blocks_.size(); ++i) {
    const Shape ys = blocks_[i]->output_shape(x.shape());
    const k::PlaneLayout out =
        i + 1 < blocks_.size() ? blocks_[i + 1]->input_layout(t, ys) : k::PlaneLayout{};
    x = blocks_[i]->forward(t, x, out);
  }
  x = global_avg_pool(t, x);
  x = reshape(t, x, Shape{x.shape()[0], x.shape()[1]});
  return linear(t, x, fc_, Var());
}

}  // namespace vkjr2::nets
