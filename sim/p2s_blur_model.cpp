#include <vkjr2/kernels/check.hpp>
#include <vkjr2/kernels/conv2d.hpp>
#include <vkjr2/runtime/error.hpp>
#include <vkjr2/sim/p2s_blur_model.hpp>

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <string>
#include <vector>

namespace vkjr2::sim {
namespace {

constexpr float kLeakySlope = 0.2f;  // P2sNet's hidden activation

// Linear weight [in, out] (y = x·W) → row-major [out, in] (a 1×1 conv
// weight), input i scaled by in_scale[i], outputs by out_scale.
std::vector<float> conv_rows(const nets::Var& linear_weight, const std::vector<float>& in_scale,
                             float out_scale) {
  const std::int64_t in = linear_weight.shape()[0], out = linear_weight.shape()[1];
  const std::vector<float> w = linear_weight.value().download();
  std::vector<float> c(w.size());
  for (std::int64_t i = 0; i < in; ++i) {
    const float s = in_scale.empty() ? 1.f : in_scale[std::size_t(i)];
    for (std::int64_t o = 0; o < out; ++o)
      c[std::size_t(o * in + i)] = w[std::size_t(i * out + o)] * s * out_scale;
  }
  return c;
}

}  // namespace

P2sBlurModel::P2sBlurModel(const Device& device, const P2sModel& model)
    : device_(device),
      j_max_(model.net->config().j_max),
      hidden_(model.net->config().hidden),
      count_(model.basis.count()),
      nyquist_(model.basis.nyquist) {
  const PsfBasis& b = model.basis;
  basis_ = Tensor::from(device_, {b.count(), b.size, b.size}, b.kernels);
  const P2sNet& net = *model.net;
  const float out_scale = net.config().output_scale;
  w1_host_ = conv_rows(net.l1.weight, net.input_scale.value().download(), 1.f);
  b1_ = net.l1.bias.value();
  w2_ = Tensor::from(device_, {hidden_, hidden_, 1, 1}, conv_rows(net.l2.weight, {}, 1.f));
  b2_ = net.l2.bias.value();
  // The last layer with a leading β_0 row: zero weights, bias 1.
  std::vector<float> w3(std::size_t(hidden_), 0.f), b3{1.f};
  const auto rows = conv_rows(net.l3.weight, {}, out_scale);
  w3.insert(w3.end(), rows.begin(), rows.end());
  for (float v : net.l3.bias.value().download()) b3.push_back(v * out_scale);
  w3_ = Tensor::from(device_, {count_, hidden_, 1, 1}, w3);
  b3_ = Tensor::from(device_, {count_}, b3);
}

const Tensor& P2sBlurModel::first_layer(std::int64_t planes, float scale) const {
  for (const FirstLayer& l : w1_)
    if (l.planes == planes && l.scale == scale) return l.weight;
  const std::int64_t inputs = j_max_ - 3;
  std::vector<float> w(std::size_t(hidden_ * planes), 0.f);
  for (std::int64_t o = 0; o < hidden_; ++o)
    for (std::int64_t i = 0; i < inputs; ++i)
      w[std::size_t(o * planes + 2 + i)] = w1_host_[std::size_t(o * inputs + i)] * scale;
  w1_.push_back({planes, scale, Tensor::from(device_, {hidden_, planes, 1, 1}, w)});
  return w1_.back().weight;
}

void P2sBlurModel::weights(Stream& stream, const Tensor& coefficients, const Tensor& beta,
                           float coefficient_scale) const {
  const char* op = "P2sBlurModel::weights";
  kernels::require_f32_rank(coefficients, 4, op, "coefficients");
  const Shape& cs = coefficients.shape();
  if (!std::isfinite(coefficient_scale) || coefficient_scale <= 0) {
    throw InvalidArgument(
        op, "coefficient_scale " + std::to_string(coefficient_scale) + " is not a positive number",
        "pass λ_0/λ_c > 0");
  }
  if (cs[1] + 1 < j_max_) {
    throw InvalidArgument(op, "coefficients " + cs.str() + " hold a_2..a_" +
                                  std::to_string(cs[1] + 1) + "; the model reads a_4..a_" +
                                  std::to_string(j_max_));
  }
  const std::int64_t n = cs[0], h = cs[2], w = cs[3];
  kernels::require_shape(beta, Shape{n, count_, h, w}, op, "beta");
  kernels::Conv2dParams hidden;
  hidden.activation = kernels::Activation::leaky_relu;
  hidden.leaky_slope = kLeakySlope;
  const Tensor t1 = Tensor::empty(device_, {n, hidden_, h, w});
  const Tensor t2 = Tensor::empty(device_, {n, hidden_, h, w});
  kernels::conv2d(stream, coefficients, first_layer(cs[1], coefficient_scale), &b1_, t1, hidden);
  kernels::conv2d(stream, t1, w2_, &b2_, t2, hidden);
  kernels::conv2d(stream, t2, w3_, &b3_, beta, {});
}

std::shared_ptr<const BlurModel> load_blur_model(const Device& device,
                                                 const std::filesystem::path& path) {
  const P2sModel model = load_p2s_model(device, path);
  return std::make_shared<P2sBlurModel>(device, model);
}

std::filesystem::path default_blur_model_path() {
  constexpr const char* kName = "p2s_default.safetensors";
  if (const char* dir = std::getenv("VKJR2_ARTIFACT_DIR"); dir != nullptr && *dir != '\0') {
    return std::filesystem::path(dir) / kName;
  }
  std::filesystem::path installed = std::filesystem::path(VKJR2_INSTALL_ARTIFACT_DIR) / kName;
  if (std::filesystem::exists(installed)) return installed;
  return std::filesystem::path(VKJR2_SOURCE_ARTIFACT_DIR) / kName;
}

std::shared_ptr<const BlurModel> load_default_blur_model(const Device& device) {
  const std::filesystem::path path = default_blur_model_path();
  if (!std::filesystem::exists(path)) {
    throw Error(
        "load_default_blur_model", "the shipped blur model " + path.string() + " is missing",
        "set VKJR2_ARTIFACT_DIR to the folder holding p2s_default.safetensors, make one with "
        "`vkjr2 sim-train`, or pass --no-blur");
  }
  return load_blur_model(device, path);
}

std::vector<std::filesystem::path> shipped_blur_model_paths() {
  namespace fs = std::filesystem;
  const fs::path first = default_blur_model_path();
  std::vector<fs::path> paths;
  if (fs::exists(first)) paths.push_back(first);
  std::error_code ec;
  std::vector<fs::path> others;
  for (const auto& e : fs::directory_iterator(first.parent_path(), ec)) {
    const std::string name = e.path().filename().string();
    if (e.is_regular_file(ec) && name.starts_with("p2s_") &&
        e.path().extension() == ".safetensors" && e.path().filename() != first.filename()) {
      others.push_back(e.path());
    }
  }
  std::sort(others.begin(), others.end());
  paths.insert(paths.end(), others.begin(), others.end());
  return paths;
}

std::vector<std::shared_ptr<const BlurModel>> load_shipped_blur_models(const Device& device) {
  const auto paths = shipped_blur_model_paths();
  if (paths.empty()) {
    throw Error("load_shipped_blur_models",
                "no shipped blur model (p2s_*.safetensors) in " +
                    default_blur_model_path().parent_path().string(),
                "set VKJR2_ARTIFACT_DIR to the folder holding them, make one with "
                "`vkjr2 sim-train`, or pass --no-blur");
  }
  std::vector<std::shared_ptr<const BlurModel>> models;
  for (const auto& p : paths) models.push_back(load_blur_model(device, p));
  return models;
}

}  // namespace vkjr2::sim
