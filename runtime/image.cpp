#include <vkjr2/runtime/error.hpp>
#include <vkjr2/runtime/image.hpp>

#include <algorithm>
#include <array>
#include <string>

namespace vkjr2 {
namespace {

// [H, W, C] of an H×W×C or 1×H×W×C image; throws otherwise.
std::array<std::int64_t, 3> image_dims(const HostTensor& img, const char* op) {
  std::vector<std::int64_t> s = img.shape;
  if (s.size() == 4 && s[0] == 1) s.erase(s.begin());
  if (s.size() != 3 || s[0] <= 0 || s[1] <= 0 || s[2] <= 0 ||
      std::int64_t(img.values.size()) != s[0] * s[1] * s[2]) {
    throw InvalidArgument(op, "image has shape " + shape_str(img.shape),
                          "pass an H×W×C float image (e.g. a .npy of shape (h, w, 3))");
  }
  return {s[0], s[1], s[2]};
}

}  // namespace

std::vector<float> image_to_planes(const HostTensor& img, int channels, float range) {
  const auto [h, w, c] = image_dims(img, "image_to_planes");
  const std::int64_t out_c = channels == 0 ? c : channels;
  if (out_c != c && !(out_c == 1 && c == 3) && !(out_c == 3 && c == 1)) {
    throw InvalidArgument(
        "image_to_planes",
        std::to_string(out_c) + " planes asked of a " + std::to_string(c) + "-channel image",
        "ask for its own channels, grey (1) from RGB, or RGB (3) from grey");
  }
  const auto hw = std::size_t(h * w);
  const auto cs = std::size_t(c);
  std::vector<float> out(hw * std::size_t(out_c));
  for (std::size_t i = 0; i < hw; ++i) {
    const float* px = &img.values[i * cs];
    if (out_c == 1 && c == 3) {
      out[i] = (px[0] + px[1] + px[2]) / (3 * range);
    } else {
      for (std::size_t k = 0; k < std::size_t(out_c); ++k) {
        out[k * hw + i] = px[c == 1 ? 0 : k] / range;
      }
    }
  }
  return out;
}

Tensor image_to_device(const Device& device, const HostTensor& img, int channels, float range) {
  const auto [h, w, c] = image_dims(img, "image_to_device");
  const std::int64_t out_c = channels == 0 ? c : channels;
  return Tensor::from(device, Shape{1, out_c, h, w}, image_to_planes(img, channels, range));
}

HostTensor planes_to_image(std::span<const float> planes, int channels, std::int64_t height,
                           std::int64_t width, int out_channels, float range) {
  const auto hw = std::size_t(height * width);
  if (channels < 1 || height < 1 || width < 1 || planes.size() != hw * std::size_t(channels) ||
      (out_channels != channels && !(channels == 1 && out_channels == 3))) {
    throw InvalidArgument("planes_to_image",
                          std::to_string(planes.size()) + " values as " + std::to_string(channels) +
                              " planes of " + std::to_string(height) + "×" + std::to_string(width) +
                              " into " + std::to_string(out_channels) + " channels",
                          "pass [C, H, W] planes; one plane may become 3 channels");
  }
  HostTensor img;
  img.shape = {height, width, out_channels};
  img.values.resize(hw * std::size_t(out_channels));
  for (std::size_t i = 0; i < hw; ++i) {
    for (std::size_t k = 0; k < std::size_t(out_channels); ++k) {
      const float v = planes[(channels == 1 ? 0 : k) * hw + i];
      img.values[i * std::size_t(out_channels) + k] =
          range > 0 ? std::clamp(v, 0.f, 1.f) * range : v;
    }
  }
  return img;
}

HostTensor image_to_host(const Tensor& t) {
  const Shape& s = t.shape();
  if (s.rank() != 4) {
    throw InvalidArgument("image_to_host", "tensor has shape " + s.str(), "pass an NCHW tensor");
  }
  const std::vector<float> all = t.download();
  const std::size_t first = std::size_t(s[1] * s[2] * s[3]);
  return planes_to_image(std::span<const float>(all).first(first), int(s[1]), s[2], s[3],
                         int(s[1]));
}

}  // namespace vkjr2
