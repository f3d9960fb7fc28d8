#include <vkjr2/kernels/resize.hpp>
#include <vkjr2/nets/face_common.hpp>
#include <vkjr2/nets/ops.hpp>
#include <vkjr2/nets/tfjs_weights.hpp>
#include <vkjr2/runtime/error.hpp>

#include <algorithm>
#include <cstdlib>
#include <string>

namespace vkjr2::nets {
namespace {

void require_rank(const HostTensor& t, std::size_t rank, const char* op, const char* name) {
  if (t.shape.size() != rank || std::int64_t(t.values.size()) != t.numel()) {
    throw InvalidArgument(op,
                          std::string("weight '") + name + "' has shape " + shape_str(t.shape) +
                              ", expected rank " + std::to_string(rank),
                          "the model file does not match this network: re-run scripts/setup");
  }
}

}  // namespace

std::filesystem::path face_api_model_dir() {
  std::filesystem::path dir;
  if (const char* env = std::getenv("VKJR2_FACE_API_DIR"); env != nullptr && *env != 0) {
    dir = env;
  } else {
    std::filesystem::path cache;
    if (const char* c = std::getenv("VKJR2_CACHE_DIR"); c != nullptr && *c != 0) {
      cache = c;
    } else if (const char* home = std::getenv("HOME"); home != nullptr && *home != 0) {
      cache = std::filesystem::path(home) / ".cache" / "vkjr2";
    } else {
      throw Error("face_api_model_dir",
                  "neither VKJR2_FACE_API_DIR, VKJR2_CACHE_DIR nor HOME is set",
                  "set VKJR2_FACE_API_DIR to face-api's model/ folder");
    }
    dir = cache / "face-api-1.7.15" / "model";
  }
  if (!std::filesystem::is_directory(dir)) {
    throw Error("face_api_model_dir", "face-api models not found at " + dir.string(),
                "run scripts/setup (it fetches @vladmandic/face-api 1.7.15 from npm), or set "
                "VKJR2_FACE_API_DIR");
  }
  return dir;
}

std::filesystem::path face_api_manifest(const char* manifest) {
  auto path = face_api_model_dir() / manifest;
  if (!std::filesystem::is_regular_file(path)) {
    throw Error("face_api_manifest", "missing " + path.string(),
                "run scripts/setup again (the model folder is incomplete)");
  }
  return path;
}

Tensor conv_weight_from_hwio(const Device& device, const HostTensor& w, const char* name) {
  require_rank(w, 4, "conv_weight_from_hwio", name);
  const std::int64_t kh = w.shape[0], kw = w.shape[1], ci = w.shape[2], co = w.shape[3];
  std::vector<float> oihw(w.values.size());
  for (std::int64_t y = 0; y < kh; ++y)
    for (std::int64_t x = 0; x < kw; ++x)
      for (std::int64_t i = 0; i < ci; ++i)
        for (std::int64_t o = 0; o < co; ++o)
          oihw[std::size_t(((o * ci + i) * kh + y) * kw + x)] =
              w.values[std::size_t(((y * kw + x) * ci + i) * co + o)];
  return Tensor::from(device, Shape{co, ci, kh, kw}, oihw);
}

Tensor depthwise_weight_from_hwio(const Device& device, const HostTensor& w, const char* name) {
  require_rank(w, 4, "depthwise_weight_from_hwio", name);
  const std::int64_t kh = w.shape[0], kw = w.shape[1], c = w.shape[2], m = w.shape[3];
  std::vector<float> out(w.values.size());
  for (std::int64_t y = 0; y < kh; ++y)
    for (std::int64_t x = 0; x < kw; ++x)
      for (std::int64_t i = 0; i < c; ++i)
        for (std::int64_t j = 0; j < m; ++j)
          out[std::size_t(((i * m + j) * kh + y) * kw + x)] =
              w.values[std::size_t(((y * kw + x) * c + i) * m + j)];
  return Tensor::from(device, Shape{c * m, 1, kh, kw}, out);
}

InputAffine mean_rgb_affine(const Device& device, const std::array<float, 3>& mean_rgb) {
  InputAffine a;
  a.scale.assign(3, 1.f / 255.f);
  a.shift.resize(3);
  for (std::size_t c = 0; c < 3; ++c) a.shift[c] = -mean_rgb[c] / 255.f;
  a.scale_var = Var(Tensor::from(device, Shape{3}, a.scale));
  a.shift_var = Var(Tensor::from(device, Shape{3}, a.shift));
  return a;
}

Tensor vector_from(const Device& device, const HostTensor& v, std::int64_t expected,
                   const char* name) {
  if (v.numel() != expected || std::int64_t(v.values.size()) != expected) {
    throw InvalidArgument("vector_from",
                          std::string("weight '") + name + "' has shape " + shape_str(v.shape) +
                              ", expected " + std::to_string(expected) + " values",
                          "the model file does not match this network: re-run scripts/setup");
  }
  return Tensor::from(device, Shape{expected}, v.values);
}

WeightReader::WeightReader(const TfjsWeights& weights, std::string model, std::string manifest)
    : weights_(weights), model_(std::move(model)), manifest_(std::move(manifest)) {}

void WeightReader::fail(const std::string& name, const std::string& problem) const {
  throw InvalidArgument(model_, "weight '" + name + "' in " + weights_.source() + " " + problem,
                        "use face-api 1.7.15's " + manifest_ + " (re-run scripts/setup)");
}

const HostTensor& WeightReader::take(const std::string& name,
                                     const std::vector<std::int64_t>& shape) {
  const HostTensor& t = weights_.at(name);  // throws naming the missing weight
  if (t.shape != shape) {
    fail(name, "has shape " + shape_str(t.shape) + ", expected " + shape_str(shape));
  }
  if (!used_.insert(name).second) fail(name, "is used twice");
  return t;
}

Tensor WeightReader::conv(const Device& d, const std::string& name,
                          const std::vector<std::int64_t>& shape) {
  return conv_weight_from_hwio(d, take(name, shape), name.c_str());
}

Tensor WeightReader::depthwise(const Device& d, const std::string& name, std::int64_t channels) {
  return depthwise_weight_from_hwio(d, take(name, {3, 3, channels, 1}), name.c_str());
}

Tensor WeightReader::vec(const Device& d, const std::string& name, std::int64_t n) {
  return vector_from(d, take(name, {n}), n, name.c_str());
}

void WeightReader::finish() const {
  for (const auto& [name, tensor] : weights_.entries()) {
    if (used_.count(name) == 0) fail(name, "is not part of " + model_);
  }
}

kernels::ResizeCanvas square_canvas(std::int64_t h, std::int64_t w) {
  const std::int64_t side = std::max(h, w);
  const auto after = std::int64_t(js_round_half(std::abs(h - w)));
  const std::int64_t before = std::abs(h - w) - after;
  return {side, side, h > w ? 0 : before, h > w ? before : 0};
}

Var resize_normalized(Tape& t, const Tensor& image, const kernels::ResizeCanvas& canvas,
                      const Shape& shape, const Var& scale, const Var& shift,
                      const kernels::PlaneLayout& layout, Tensor& nonfinite) {
  Stream& stream = t.stream();
  nonfinite = Tensor::empty(image.device(), Shape{1});
  stream.fill(nonfinite, 0.f);
  const kernels::Planes x = kernels::Planes::make(stream, shape, layout);
  kernels::resize_into_padded(stream, image, canvas, kernels::ResizeMode::bilinear_legacy,
                              scale.value(), shift.value(), x, &nonfinite);
  return Var(x);
}

Var pad_to_square_and_resize(Tape& t, const Var& image, std::int64_t size) {
  const std::int64_t h = image.shape()[2], w = image.shape()[3];
  const kernels::ResizeCanvas canvas = square_canvas(h, w);
  const std::int64_t side = canvas.height;
  const auto legacy = kernels::ResizeMode::bilinear_legacy;
  if (side != size && !t.needs_grad({&image})) {
    Tensor y = Tensor::empty(image.value().device(),
                             Shape{image.shape()[0], image.shape()[1], size, size});
    kernels::resize_zero_padded(t.stream(), image.value(), canvas, legacy, y);
    return Var(y);
  }
  kernels::Pad2d p;
  p.top = std::int32_t(canvas.top);
  p.left = std::int32_t(canvas.left);
  p.bottom = std::int32_t(side - h - canvas.top);
  p.right = std::int32_t(side - w - canvas.left);
  Var square = h != w ? pad(t, image, p, 0.f) : image;
  if (side == size) return square;
  return resize(t, square, legacy, size, size);
}

}  // namespace vkjr2::nets
