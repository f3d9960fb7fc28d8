#include <vkjr2/jr2/restorer.hpp>
#include <vkjr2/kernels/activation.hpp>
#include <vkjr2/kernels/basic.hpp>
#include <vkjr2/kernels/conv2d.hpp>
#include <vkjr2/kernels/elementwise.hpp>
#include <vkjr2/kernels/layout.hpp>
#include <vkjr2/nets/checkpoint.hpp>
#include <vkjr2/nets/ops.hpp>
#include <vkjr2/nets/safetensors.hpp>
#include <vkjr2/runtime/error.hpp>
#include <vkjr2/sim/p2s_blur_model.hpp>

#include <algorithm>
#include <charconv>
#include <cmath>
#include <numbers>
#include <utility>

#include "internal/text_and_draws.hpp"

namespace vkjr2::jr2 {
namespace {

using nets::Conv2d;
using nets::Tape;
using nets::Var;

constexpr const char* kNetwork = "vkjr2.restorer";
constexpr float kNormEps = 1e-6f;  // NAFNet's LayerNorm2d

// Distinct, reproducible seeds for the layers of one network.
class Seeds {
 public:
  explicit Seeds(std::uint32_t seed) : state_(seed) {}
  std::uint32_t next() {
    return std::uint32_t(detail::splitmix_finalize(state_ += detail::kGoldenGamma) >> 32);
  }

 private:
  std::uint64_t state_;
};

kernels::Conv2dParams conv_params(int pad, int stride = 1, int groups = 1) {
  kernels::Conv2dParams p;
  p.stride_y = p.stride_x = stride;
  p.pad = {pad, pad, pad, pad};
  p.groups = groups;
  return p;
}

std::string join(const std::vector<int>& v) {
  std::string s;
  for (std::size_t i = 0; i < v.size(); ++i) s += (i ? "," : "") + std::to_string(v[i]);
  return s;
}

int parse_int(const std::string& text, const std::string& what) {
  int v = 0;
  const char* end = text.data() + text.size();
  const auto [ptr, ec] = std::from_chars(text.data(), end, v);
  if (ec != std::errc() || ptr != end || text.empty()) {
    throw InvalidArgument("restorer", what + " is \"" + text + "\", not a whole number",
                          "write a whole number");
  }
  return v;
}

// Multiply-adds of a convolution over an output of `pixels` pixels.
double conv_macs(int cin, int cout, int k, int groups, double pixels) {
  const int per_group = cin / groups;
  return double(cout) * double(per_group) * k * k * pixels;
}

// One NAFBlock of width c over `pixels` pixels: its convolutions' multiply-adds
// ×2, plus one FLOP per element for each norm (≈ 8 per value), gate,
// attention scale and β/γ residual.
double block_flops(int c, double pixels) {
  const double macs = conv_macs(c, 2 * c, 1, 1, pixels) +
                      conv_macs(2 * c, 2 * c, 3, 2 * c, pixels) + conv_macs(c, c, 1, 1, 1) +
                      conv_macs(c, c, 1, 1, pixels) + conv_macs(c, 2 * c, 1, 1, pixels) +
                      conv_macs(c, c, 1, 1, pixels);
  const double elementwise = pixels * c * (2 * 8 + 2 + 1 + 1 + 2 * 2);
  return 2 * macs + elementwise;
}

std::int64_t block_params(int c) {
  const std::int64_t cc = c;
  return 4 * cc                    // two norms
         + (2 * cc * cc + 2 * cc)  // conv1
         + (2 * cc * 9 + 2 * cc)   // conv2 (depthwise)
         + (cc * cc + cc) * 2      // sca, conv3
         + (2 * cc * cc + 2 * cc)  // conv4
         + (cc * cc + cc)          // conv5
         + 2 * cc;                 // β, γ
}

// The 2×2 stride-2 conv as pixel_unshuffle(2) and a 1×1 conv: OIHW
// [2c, c, 2, 2] is, in memory, the [2c, 4c, 1, 1] weight over the unshuffled
// channels c·4 + 2i + j, so both run on the pointwise kernels (forward and
// backward) instead of the general strided ones.
Var down(Tape& t, const Conv2d& conv, const Var& x) {
  const Shape& w = conv.weight.shape();
  const Var weight = nets::reshape(t, conv.weight, Shape{w[0], w[1] * 4, 1, 1});
  return nets::conv2d(t, nets::pixel_unshuffle(t, x, 2), weight, conv.bias, conv_params(0));
}

}  // namespace

std::vector<int> parse_block_list(const std::string& text, const std::string& what) {
  std::vector<int> out;
  std::size_t start = 0;
  while (start <= text.size()) {
    const std::size_t comma = text.find(',', start);
    const std::string item =
        text.substr(start, comma == std::string::npos ? std::string::npos : comma - start);
    std::string where = what;
    where += " (\"" + text + "\")";
    const int v = parse_int(item, where);
    out.push_back(v);
    if (comma == std::string::npos) break;
    start = comma + 1;
  }
  return out;
}

void RestorerConfig::validate() const {
  const char* op = "restorer";
  if (frames < 1 || frames > 64) {
    throw InvalidArgument(op, "frames = " + std::to_string(frames), "use 1..64 input frames");
  }
  if (width < 2 || width % 2 != 0 || width > 256) {
    throw InvalidArgument(op, "width = " + std::to_string(width),
                          "use an even width in 2..256 (16 is the default)");
  }
  if (enc_blocks.empty() || enc_blocks.size() > 5) {
    throw InvalidArgument(op, std::to_string(enc_blocks.size()) + " encoder levels",
                          "use 1..5 levels (--enc-blocks 1,1,1)");
  }
  if (dec_blocks.size() != enc_blocks.size()) {
    throw InvalidArgument(op,
                          std::to_string(enc_blocks.size()) + " encoder levels but " +
                              std::to_string(dec_blocks.size()) + " decoder levels",
                          "give as many decoder as encoder levels");
  }
  for (const auto* list : {&enc_blocks, &dec_blocks}) {
    for (int b : *list) {
      if (b < 0 || b > 32) {
        throw InvalidArgument(op, "a level with " + std::to_string(b) + " blocks",
                              "use 0..32 blocks per level");
      }
    }
  }
  if (middle_blocks < 0 || middle_blocks > 32) {
    throw InvalidArgument(op, "middle_blocks = " + std::to_string(middle_blocks),
                          "use 0..32 middle blocks");
  }
}

std::int64_t RestorerConfig::parameter_count() const {
  validate();
  const int levels = this->levels();
  std::int64_t n = (std::int64_t(width) * 3 * frames * 9 + width) + (3LL * width * 9 + 3);
  for (int i = 0; i < levels; ++i) {
    const std::int64_t c = std::int64_t(width) << i;
    n += enc_blocks[std::size_t(i)] * block_params(int(c));
    n += 2 * c * c * 4 + 2 * c;  // down
  }
  n += middle_blocks * block_params(width << levels);
  for (int i = 0; i < levels; ++i) {
    const std::int64_t c = std::int64_t(width) << (levels - i);
    n += 2 * c * c;  // up (no bias)
    n += dec_blocks[std::size_t(i)] * block_params(int(c / 2));
  }
  return n;
}

double RestorerConfig::flops(std::int64_t height, std::int64_t w) const {
  validate();
  const int levels = this->levels();
  const std::int64_t m = std::int64_t(1) << levels;
  const std::int64_t hp_px = (height + m - 1) / m * m, wp_px = (w + m - 1) / m * m;
  const double hp = double(hp_px), wp = double(wp_px);
  double f = 2 * (conv_macs(3 * frames, width, 3, 1, hp * wp) + conv_macs(width, 3, 3, 1, hp * wp));
  f += 3 * hp * wp;  // + the reference frame
  for (int i = 0; i < levels; ++i) {
    const int c = width << i;
    const double px = hp * wp / double(1 << (2 * i));
    f += enc_blocks[std::size_t(i)] * block_flops(c, px);
    f += 2 * conv_macs(c, 2 * c, 2, 1, px / 4);
  }
  const double deep = hp * wp / double(std::int64_t(1) << (2 * levels));
  f += middle_blocks * block_flops(width << levels, deep);
  for (int i = 0; i < levels; ++i) {
    const int c = width << (levels - i);
    const double px = hp * wp / double(std::int64_t(1) << (2 * (levels - i)));
    f += 2 * conv_macs(c, 2 * c, 1, 1, px);
    const int half = c / 2;
    f += double(half) * px * 4;  // the skip's add
    f += dec_blocks[std::size_t(i)] * block_flops(half, px * 4);
  }
  return f;
}

std::map<std::string, std::string> RestorerConfig::metadata() const {
  return {{"network", kNetwork},
          {"frames", std::to_string(frames)},
          {"width", std::to_string(width)},
          {"enc_blocks", join(enc_blocks)},
          {"middle_blocks", std::to_string(middle_blocks)},
          {"dec_blocks", join(dec_blocks)}};
}

RestorerConfig RestorerConfig::from_metadata(const std::map<std::string, std::string>& meta,
                                             const std::string& source) {
  auto get = [&](const char* key) -> const std::string& {
    const auto it = meta.find(key);
    if (it == meta.end()) {
      throw InvalidArgument("restorer",
                            source + " has no metadata \"" + key + "\": not a restorer file",
                            "pass a file written by vkjr2 restore-train");
    }
    return it->second;
  };
  if (get("network") != kNetwork) {
    throw InvalidArgument("restorer", source + " holds a \"" + get("network") + "\" network",
                          "pass a restorer file (network \"" + std::string(kNetwork) + "\")");
  }
  RestorerConfig c;
  c.frames = parse_int(get("frames"), source + " metadata frames");
  c.width = parse_int(get("width"), source + " metadata width");
  c.enc_blocks = parse_block_list(get("enc_blocks"), source + " metadata enc_blocks");
  c.middle_blocks = parse_int(get("middle_blocks"), source + " metadata middle_blocks");
  c.dec_blocks = parse_block_list(get("dec_blocks"), source + " metadata dec_blocks");
  c.validate();
  return c;
}

NafBlock::NafBlock(const Device& device, int c, std::uint32_t seed) {
  Seeds seeds(seed);
  auto ones = std::vector<float>(std::size_t(c), 1.f), zeros = std::vector<float>(std::size_t(c));
  norm1_weight = register_parameter("norm1.weight", Tensor::from(device, Shape{c}, ones));
  norm1_bias = register_parameter("norm1.bias", Tensor::from(device, Shape{c}, zeros));
  norm2_weight = register_parameter("norm2.weight", Tensor::from(device, Shape{c}, ones));
  norm2_bias = register_parameter("norm2.bias", Tensor::from(device, Shape{c}, zeros));
  beta = register_parameter("beta", Tensor::from(device, Shape{c}, zeros));
  gamma = register_parameter("gamma", Tensor::from(device, Shape{c}, zeros));
  auto conv = [&](const char* name, int cin, int cout, int k, int groups) {
    return &register_module(
        name, std::make_unique<Conv2d>(device, cin, cout, k, k, conv_params(k / 2, 1, groups), true,
                                       seeds.next()));
  };
  conv1_ = conv("conv1", c, 2 * c, 1, 1);
  conv2_ = conv("conv2", 2 * c, 2 * c, 3, 2 * c);
  sca_ = conv("sca", c, c, 1, 1);
  conv3_ = conv("conv3", c, c, 1, 1);
  conv4_ = conv("conv4", c, 2 * c, 1, 1);
  conv5_ = conv("conv5", c, c, 1, 1);
}

Var NafBlock::forward(Tape& t, const Var& x) const {
  Var h = nets::layer_norm_channels(t, x, norm1_weight, norm1_bias, kNormEps);
  h = nets::simple_gate(t, conv2_->forward(t, conv1_->forward(t, h)));
  h = nets::mul_sample_channel(t, h, sca_->forward(t, nets::global_avg_pool(t, h)));
  const Var y = scaled_residual(t, *conv3_, conv3_plans_, h, beta, x);
  h = nets::layer_norm_channels(t, y, norm2_weight, norm2_bias, kNormEps);
  return scaled_residual(t, *conv5_, conv5_plans_, nets::simple_gate(t, conv4_->forward(t, h)),
                         gamma, y);
}

// x + (W·h + b)·s = x + (s ⊙ W)·h + s ⊙ b: the scale applied to the [C, C]
// weight and the bias, the add in the convolution's epilogue, instead of two
// passes over the full-size activations forward (and their backward).
Var NafBlock::scaled_residual(Tape& t, const nets::Conv2d& conv, const nets::ConvPlans& plans,
                              const Var& h, const Var& scale, const Var& residual) const {
  const Shape& w = conv.weight.shape();  // [C, C, 1, 1]
  const Var weight = nets::reshape(
      t,
      nets::mul_channel(t, nets::reshape(t, conv.weight, Shape{1, w[0], w[1] * w[2] * w[3]}),
                        scale),
      w);
  const Var bias = nets::reshape(
      t, nets::mul_channel(t, nets::reshape(t, conv.bias, Shape{1, w[0]}), scale), Shape{w[0]});
  return nets::conv2d(t, h, weight, bias, conv.params, &plans, residual);
}

Restorer::Restorer(const Device& device, const RestorerConfig& config, std::uint32_t seed)
    : config_(config) {
  config_.validate();
  Seeds seeds(seed);
  const int w = config_.width, levels = config_.levels();
  auto conv = [&](const std::string& name, int cin, int cout, int k, int stride, int pad,
                  bool bias) {
    return &register_module(
        name, std::make_unique<Conv2d>(device, cin, cout, k, k, conv_params(pad, stride), bias,
                                       seeds.next()));
  };
  auto blocks = [&](const std::string& prefix, int count, int c) {
    std::vector<NafBlock*> out;
    for (int j = 0; j < count; ++j) {
      out.push_back(&register_module(prefix + std::to_string(j),
                                     std::make_unique<NafBlock>(device, c, seeds.next())));
    }
    return out;
  };
  intro_ = conv("intro", 3 * config_.frames, w, 3, 1, 1, true);
  for (int i = 0; i < levels; ++i) {
    const int c = w << i;
    encoders_.push_back(
        blocks("encoders." + std::to_string(i) + ".", config_.enc_blocks[std::size_t(i)], c));
    downs_.push_back(conv("downs." + std::to_string(i), c, 2 * c, 2, 2, 0, true));
  }
  middle_ = blocks("middle.", config_.middle_blocks, w << levels);
  for (int i = 0; i < levels; ++i) {
    const int c = w << (levels - i);
    ups_.push_back(conv("ups." + std::to_string(i), c, 2 * c, 1, 1, 0, false));
    decoders_.push_back(
        blocks("decoders." + std::to_string(i) + ".", config_.dec_blocks[std::size_t(i)], c / 2));
  }
  ending_ = conv("ending", w, 3, 3, 1, 1, true);
}

std::unique_ptr<Restorer> Restorer::load(const Device& device, const std::filesystem::path& path) {
  const nets::SafetensorsFile file = nets::read_safetensors(path);
  const RestorerConfig config = RestorerConfig::from_metadata(file.metadata, path.string());
  auto net = std::make_unique<Restorer>(device, config, 0);
  nets::load_checkpoint(path, *net, nullptr);
  return net;
}

void Restorer::save(const std::filesystem::path& path,
                    const std::map<std::string, std::string>& metadata) const {
  std::map<std::string, std::string> meta = metadata;
  for (auto& [k, v] : config_.metadata()) meta[k] = v;
  nets::save_checkpoint(path, *this, nullptr, meta);
}

std::filesystem::path default_restorer_path() {
  return sim::default_blur_model_path().parent_path() / "restorer_default.safetensors";
}

std::vector<std::size_t> restore_window(std::size_t count, std::size_t index, int frames) {
  if (count == 0 || index >= count || frames < 1) {
    throw InvalidArgument("restore_window",
                          "frame " + std::to_string(index) + " of a clip of " +
                              std::to_string(count) + " for a restorer of " +
                              std::to_string(frames) + " frames",
                          "pass an index inside a non-empty clip");
  }
  std::vector<std::size_t> w(std::size_t(frames), 0);
  const auto r = std::int64_t(frames / 2);
  for (std::int64_t j = 0; j < frames; ++j) {
    const std::int64_t i = std::int64_t(index) - r + j;
    w[std::size_t(j)] = std::size_t(std::clamp<std::int64_t>(i, 0, std::int64_t(count) - 1));
  }
  return w;
}

Tensor stack_frames(Stream& stream, std::span<const Tensor> frames) {
  if (frames.empty()) {
    throw InvalidArgument("stack_frames", "no frames", "pass at least one [1, 3, H, W] frame");
  }
  const Shape& s = frames.front().shape();
  for (const Tensor& f : frames) {
    if (f.shape().rank() != 4 || !(f.shape() == s) || s[0] != 1 || s[1] != 3) {
      throw InvalidArgument("stack_frames", "a frame of shape " + f.shape().str(),
                            "pass frames of one shape [1, 3, H, W]");
    }
  }
  Tensor y = Tensor::empty(stream.device(), Shape{1, 3 * std::int64_t(frames.size()), s[2], s[3]});
  kernels::concat_channels(stream, frames, y);
  return y;
}

Tensor to_pixels(Stream& stream, const Tensor& unit) {
  const Device& dev = stream.device();
  const Tensor a = Tensor::empty(dev, unit.shape());
  Tensor b = Tensor::empty(dev, unit.shape());
  kernels::relu(stream, unit, a);                     // max(x, 0)
  kernels::scale_shift(stream, a, -1.f, 1.f, b);      // 1 − max(x, 0)
  kernels::relu(stream, b, a);                        // max(1 − max(x, 0), 0)
  kernels::scale_shift(stream, a, -255.f, 255.f, b);  // 255·min(max(x, 0), 1)
  return b;
}

Tensor classical_restore(Stream& stream, std::span<const Tensor> frames,
                         const ClassicalOptions& o) {
  if (!(o.sigma_px > 0 && o.sigma_px <= 20) || !(o.amount >= 0 && o.amount <= 10)) {
    throw InvalidArgument(
        "classical_restore",
        "sigma " + std::to_string(o.sigma_px) + " px, amount " + std::to_string(o.amount),
        "use 0 < sigma <= 20 px and 0 <= amount <= 10");
  }
  const Tensor x = stack_frames(stream, frames);
  const Device& dev = stream.device();
  const auto t = std::int64_t(frames.size());
  const std::int64_t h = x.shape()[2], w = x.shape()[3];
  // The mean as a 1×1 conv: out channel c averages channels 3f + c.
  std::vector<float> mean_w(std::size_t(3 * 3 * t), 0.f);
  for (std::int64_t c = 0; c < 3; ++c) {
    for (std::int64_t f = 0; f < t; ++f)
      mean_w[std::size_t(c * 3 * t + 3 * f + c)] = 1.f / float(t);
  }
  const Tensor mean = Tensor::empty(dev, Shape{1, 3, h, w});
  kernels::conv2d(stream, x, Tensor::from(dev, Shape{3, 3 * t, 1, 1}, mean_w), nullptr, mean,
                  conv_params(0));
  // Gaussian blur (depthwise, zero padding), then divided by the weight
  // inside the image (a product with the host-computed reciprocal).
  const int r = int(std::ceil(3 * o.sigma_px));
  const int k = 2 * r + 1;
  std::vector<double> g(static_cast<std::size_t>(k));
  double gs = 0;
  for (int i = 0; i < k; ++i) {
    g[std::size_t(i)] = std::exp(-0.5 * std::pow((i - r) / o.sigma_px, 2));
    gs += g[std::size_t(i)];
  }
  for (double& v : g) v /= gs;
  std::vector<float> gw(std::size_t(3 * k * k));
  for (int c = 0; c < 3; ++c) {
    for (int i = 0; i < k; ++i) {
      for (int j = 0; j < k; ++j) {
        gw[(std::size_t(c) * std::size_t(k) + std::size_t(i)) * std::size_t(k) + std::size_t(j)] =
            float(g[std::size_t(i)] * g[std::size_t(j)]);
      }
    }
  }
  auto inside = [&](std::int64_t n, std::int64_t p) {  // the 1-D weight inside [0, n)
    double a = 0;
    for (int i = 0; i < k; ++i) {
      const std::int64_t q = p + i - r;
      if (q >= 0 && q < n) a += g[std::size_t(i)];
    }
    return a;
  };
  std::vector<double> wy(static_cast<std::size_t>(h)), wx(static_cast<std::size_t>(w));
  for (std::int64_t i = 0; i < h; ++i) wy[std::size_t(i)] = inside(h, i);
  for (std::int64_t j = 0; j < w; ++j) wx[std::size_t(j)] = inside(w, j);
  std::vector<float> norm(std::size_t(3 * h * w));
  for (std::int64_t c = 0; c < 3; ++c) {
    for (std::int64_t i = 0; i < h; ++i) {
      for (std::int64_t j = 0; j < w; ++j) {
        norm[std::size_t((c * h + i) * w + j)] =
            float(1.0 / (wy[std::size_t(i)] * wx[std::size_t(j)]));
      }
    }
  }
  const Tensor blurred = Tensor::empty(dev, Shape{1, 3, h, w});
  kernels::conv2d(stream, mean, Tensor::from(dev, Shape{3, 1, k, k}, gw), nullptr, blurred,
                  conv_params(r, 1, 3));
  const Tensor normalized = Tensor::empty(dev, Shape{1, 3, h, w});
  kernels::mul(stream, blurred, Tensor::from(dev, Shape{1, 3, h, w}, norm), normalized);
  Tensor out = Tensor::empty(dev, Shape{1, 3, h, w});
  kernels::scale_shift(stream, mean, float(1 + o.amount), 0.f, out);
  kernels::axpy(stream, float(-o.amount), normalized, out);
  return out;
}

Var Restorer::forward(Tape& t, const Var& frames) const {
  const Shape& s = frames.shape();
  const std::int64_t channels = 3LL * config_.frames;
  if (s.rank() != 4 || s[1] != channels || s[2] < 1 || s[3] < 1) {
    throw InvalidArgument("Restorer::forward", "input has shape " + s.str(),
                          "pass [N, " + std::to_string(channels) + ", H, W]: " +
                              std::to_string(config_.frames) + " RGB frames on the channels");
  }
  const int levels = config_.levels();
  const std::int64_t m = std::int64_t(1) << levels;
  const std::int64_t hp = (s[2] + m - 1) / m * m, wp = (s[3] + m - 1) / m * m;
  Var input = frames;
  if (hp != s[2] || wp != s[3]) {
    input = nets::pad(t, frames, {0, std::int32_t(hp - s[2]), 0, std::int32_t(wp - s[3])});
  }
  Var x = intro_->forward(t, input);
  std::vector<Var> skips;
  for (int i = 0; i < levels; ++i) {
    for (const NafBlock* b : encoders_[std::size_t(i)]) x = b->forward(t, x);
    skips.push_back(x);
    x = down(t, *downs_[std::size_t(i)], x);
  }
  for (const NafBlock* b : middle_) x = b->forward(t, x);
  for (int i = 0; i < levels; ++i) {
    x = nets::pixel_shuffle(t, ups_[std::size_t(i)]->forward(t, x), 2);
    x = nets::add(t, x, skips[std::size_t(levels - 1 - i)]);
    for (const NafBlock* b : decoders_[std::size_t(i)]) x = b->forward(t, x);
  }
  x = ending_->forward(t, x);
  const Var reference =
      nets::slice(t, input, {3LL * config_.reference_frame(), 0, 0}, Shape{s[0], 3, hp, wp});
  Var out = nets::add(t, x, reference);
  if (hp != s[2] || wp != s[3]) out = nets::slice(t, out, {0, 0, 0}, Shape{s[0], 3, s[2], s[3]});
  return out;
}

std::vector<Region> face_regions(std::span<const nets::FaceBox> boxes, int height, int width,
                                 double margin, int multiple) {
  if (height < 1 || width < 1 || multiple < 1 || !(margin >= 0)) {
    throw InvalidArgument("jr2::face_regions",
                          "image " + std::to_string(width) + "×" + std::to_string(height) +
                              ", multiple " + std::to_string(multiple),
                          "pass a non-empty image, a multiple ≥ 1 and a margin ≥ 0");
  }
  const auto as_box = [](const Region& r) {
    return nets::FaceBox{double(r.x), double(r.y), double(r.width), double(r.height)};
  };
  std::vector<Region> out;
  for (const nets::FaceBox& b : boxes) {
    if (!(b.width > 0 && b.height > 0) || !std::isfinite(b.x) || !std::isfinite(b.y)) continue;
    const double side = std::max(b.width, b.height) * (1 + 2 * margin);
    const double cx = b.x + b.width / 2, cy = b.y + b.height / 2;
    const int s = int(std::ceil(side / multiple)) * multiple;
    const int sw = std::min(s, width), sh = std::min(s, height);
    Region r;
    r.width = sw;
    r.height = sh;
    r.x = std::clamp(int(std::lround(cx - sw / 2.0)), 0, width - sw);
    r.y = std::clamp(int(std::lround(cy - sh / 2.0)), 0, height - sh);
    const bool seen = std::any_of(out.begin(), out.end(), [&](const Region& o) {
      return nets::box_iou(as_box(r), as_box(o)) >= 0.3;
    });
    if (!seen) out.push_back(r);
  }
  return out;
}

void paste_region(std::span<float> frame, int height, int width, std::span<const float> patch,
                  const Region& r, int feather) {
  const std::size_t hw = std::size_t(height) * std::size_t(width);
  const std::size_t rhw = std::size_t(r.height) * std::size_t(r.width);
  if (r.x < 0 || r.y < 0 || r.width < 1 || r.height < 1 || r.x + r.width > width ||
      r.y + r.height > height || frame.size() != 3 * hw || patch.size() != 3 * rhw || feather < 0) {
    throw InvalidArgument("jr2::paste_region", "the region or the buffers do not fit the frame",
                          "pass a region inside the frame and a [3, h, w] patch");
  }
  // Weight along one axis: 1 inside, a raised cosine over `feather` pixels
  // at an edge that is not the image's.
  auto ramp = [&](int i, int n, bool lo_free, bool hi_free) {
    double w = 1;
    const double f = std::min(feather, n / 2);
    if (f <= 0) return w;
    if (lo_free && i < f) w = std::min(w, 0.5 - 0.5 * std::cos(std::numbers::pi * (i + 0.5) / f));
    if (hi_free && n - 1 - i < f)
      w = std::min(w, 0.5 - 0.5 * std::cos(std::numbers::pi * (n - i - 0.5) / f));
    return w;
  };
  std::vector<double> wx(std::size_t(r.width));
  for (int x = 0; x < r.width; ++x) {
    wx[std::size_t(x)] = ramp(x, r.width, r.x > 0, r.x + r.width < width);
  }
  for (int y = 0; y < r.height; ++y) {
    const double wy = ramp(y, r.height, r.y > 0, r.y + r.height < height);
    for (int x = 0; x < r.width; ++x) {
      const double w = wy * wx[std::size_t(x)];
      for (std::size_t c = 0; c < 3; ++c) {
        float& dst =
            frame[c * hw + std::size_t(r.y + y) * std::size_t(width) + std::size_t(r.x + x)];
        const float src = patch[c * rhw + std::size_t(y) * std::size_t(r.width) + std::size_t(x)];
        dst = float((1 - w) * double(dst) + w * double(src));
      }
    }
  }
}

}  // namespace vkjr2::jr2
