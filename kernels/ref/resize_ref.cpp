#include <vkjr2/kernels/ref/resize_ref.hpp>

#include <algorithm>
#include <cmath>

namespace vkjr2::ref {
namespace {

using kernels::ResizeMode;

struct Taps {
  std::int64_t i0, i1;
  double l;  // weight of i1
};

// Source coordinate in fp32 (as the device and PyTorch compute it), then taps.
Taps taps(std::int64_t d, std::int64_t in, std::int64_t out, ResizeMode mode) {
  float s = 0;
  switch (mode) {
    case ResizeMode::bilinear_half_pixel:
      s = (static_cast<float>(d) + 0.5f) * (static_cast<float>(in) / static_cast<float>(out)) -
          0.5f;
      break;
    case ResizeMode::bilinear_legacy:
    case ResizeMode::nearest:
      s = static_cast<float>(d) * (static_cast<float>(in) / static_cast<float>(out));
      break;
    case ResizeMode::bilinear_align_corners:
      s = out > 1
              ? static_cast<float>(d) * (static_cast<float>(in - 1) / static_cast<float>(out - 1))
              : 0.f;
      break;
  }
  s = std::clamp(s, 0.f, static_cast<float>(in - 1));
  const auto i0 = std::min<std::int64_t>(static_cast<std::int64_t>(std::floor(s)), in - 1);
  if (mode == ResizeMode::nearest) return {i0, i0, 0.0};
  return {i0, std::min<std::int64_t>(i0 + 1, in - 1), double(s) - double(i0)};
}

}  // namespace

std::vector<float> resize(std::span<const float> x, std::int64_t planes, std::int64_t h,
                          std::int64_t w, std::int64_t oh, std::int64_t ow, ResizeMode mode) {
  std::vector<float> y(static_cast<std::size_t>(planes * oh * ow));
  for (std::int64_t p = 0; p < planes; ++p) {
    const float* xp = x.data() + p * h * w;
    for (std::int64_t oy = 0; oy < oh; ++oy) {
      const Taps ty = taps(oy, h, oh, mode);
      for (std::int64_t ox = 0; ox < ow; ++ox) {
        const Taps tx = taps(ox, w, ow, mode);
        auto at = [&](std::int64_t yy, std::int64_t xx) { return double(xp[yy * w + xx]); };
        const double top = (1 - tx.l) * at(ty.i0, tx.i0) + tx.l * at(ty.i0, tx.i1);
        const double bot = (1 - tx.l) * at(ty.i1, tx.i0) + tx.l * at(ty.i1, tx.i1);
        y[static_cast<std::size_t>((p * oh + oy) * ow + ox)] =
            static_cast<float>((1 - ty.l) * top + ty.l * bot);
      }
    }
  }
  return y;
}

std::vector<float> resize_backward(std::span<const float> dy, std::int64_t planes, std::int64_t h,
                                   std::int64_t w, std::int64_t oh, std::int64_t ow,
                                   ResizeMode mode) {
  std::vector<double> dx(static_cast<std::size_t>(planes * h * w), 0.0);
  for (std::int64_t p = 0; p < planes; ++p) {
    double* dp = dx.data() + p * h * w;
    for (std::int64_t oy = 0; oy < oh; ++oy) {
      const Taps ty = taps(oy, h, oh, mode);
      for (std::int64_t ox = 0; ox < ow; ++ox) {
        const Taps tx = taps(ox, w, ow, mode);
        const double g = dy[static_cast<std::size_t>((p * oh + oy) * ow + ox)];
        dp[ty.i0 * w + tx.i0] += g * (1 - ty.l) * (1 - tx.l);
        dp[ty.i0 * w + tx.i1] += g * (1 - ty.l) * tx.l;
        dp[ty.i1 * w + tx.i0] += g * ty.l * (1 - tx.l);
        dp[ty.i1 * w + tx.i1] += g * ty.l * tx.l;
      }
    }
  }
  return {dx.begin(), dx.end()};
}

}  // namespace vkjr2::ref
