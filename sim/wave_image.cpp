#include <vkjr2/runtime/error.hpp>
#include <vkjr2/sim/wave_image.hpp>

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <string>

namespace vkjr2::sim {
namespace {

int sources_along(int pixels, double step) {
  return pixels <= 1 ? 1 : static_cast<int>(std::ceil((pixels - 1) / step)) + 1;
}

// Bilinear position of pixel coordinate v on a source axis of n points
// spanning [0, pixels − 1]: lower index and weight of the upper one.
std::pair<int, double> locate(int v, int pixels, int n) {
  if (n == 1) return {0, 0.0};
  const double t = double(v) * (n - 1) / (pixels - 1);
  const int i = std::min(static_cast<int>(t), n - 2);
  return {i, t - i};
}

}  // namespace

std::vector<float> wave_image(const Device& device, const Params& params,
                              const WaveImageConfig& config, std::span<const float> x,
                              WaveImageReport* report,
                              const std::function<void(int, int)>& progress) {
  const char* op = "wave_image";
  const Derived derived = derive(params);
  const ImageShape& im = params.image;
  if (im.batch != 1)
    throw InvalidArgument(op, "takes one image (batch 1), got batch " + std::to_string(im.batch));
  const std::size_t hw = std::size_t(im.height) * std::size_t(im.width);
  if (x.size() != hw * std::size_t(im.channels)) {
    throw InvalidArgument(op, "x holds " + std::to_string(x.size()) +
                                  " values, the parameters' image " + std::to_string(im.channels) +
                                  "×" + std::to_string(im.height) + "×" + std::to_string(im.width) +
                                  " needs " + std::to_string(hw * std::size_t(im.channels)));
  }
  if (!(config.source_step_px >= 1)) throw InvalidArgument(op, "source_step_px must be >= 1");
  int s = config.psf_size;
  if (s == 0) {
    double fwhm = 0;
    for (const auto& c : derived.channels) fwhm = std::max(fwhm, c.seeing_fwhm_px);
    s = std::clamp(2 * static_cast<int>(std::ceil(4 * fwhm)) + 1, 9, 65);
  }
  if (s % 2 == 0 || s < 3 || s > 65)
    throw InvalidArgument(op, "psf_size must be odd and in 3..65, got " + std::to_string(s));
  const int ny = sources_along(im.height, config.source_step_px);
  const int nx = sources_along(im.width, config.source_step_px);
  const double ifov = derived.ifov_rad;
  // Field angles of the sources: pixel offsets from the image centre × IFOV.
  std::vector<std::array<double, 2>> angles;
  for (int r = 0; r < ny; ++r) {
    const double py = ny == 1 ? 0.0 : double(r) * (im.height - 1) / (ny - 1);
    for (int c = 0; c < nx; ++c) {
      const double px = nx == 1 ? 0.0 : double(c) * (im.width - 1) / (nx - 1);
      angles.push_back({(px - (im.width - 1) / 2.0) * ifov, (py - (im.height - 1) / 2.0) * ifov});
    }
  }
  WaveImageReport local;
  WaveImageReport& rep = report != nullptr ? *report : local;
  rep = {};
  rep.sources_y = ny;
  rep.sources_x = nx;
  rep.psf_size = s;
  std::vector<float> y(x.size(), 0.f);
  const std::size_t s2 = std::size_t(s) * std::size_t(s);
  std::vector<float> psfs, h(s2);
  std::vector<double> norm(hw), acc(hw);
  double last_lambda = -1;
  for (int ch = 0; ch < im.channels; ++ch) {
    const double lambda = channel_wavelength_m(params, ch);
    auto t0 = std::chrono::steady_clock::now();
    if (lambda != last_lambda) {
      rep.plans.push_back(plan_wave(params, ch, config.wave));
      // One row of sources per call keeps the progress moving; the screens
      // are the same for every call (same seed).
      psfs.assign(angles.size() * s2, 0.f);
      for (int r = 0; r < ny; ++r) {
        const auto row = wave_psfs(
            device, params, ch, config.wave,
            std::span(angles).subspan(std::size_t(r) * std::size_t(nx), std::size_t(nx)), s);
        std::copy(row.begin(), row.end(),
                  psfs.begin() + std::ptrdiff_t(std::size_t(r) * std::size_t(nx) * s2));
        if (progress) progress(r + 1 + ch * ny, ny * im.channels);
      }
      last_lambda = lambda;
    }
    const auto t1 = std::chrono::steady_clock::now();
    rep.psf_seconds += std::chrono::duration<double>(t1 - t0).count();
    // Scatter every pixel through its interpolated PSF.
    std::fill(norm.begin(), norm.end(), 0.0);
    std::fill(acc.begin(), acc.end(), 0.0);
    const float* xc = x.data() + std::size_t(ch) * hw;
    const int half = s / 2;
    for (int qy = 0; qy < im.height; ++qy) {
      const auto [iy, fy] = locate(qy, im.height, ny);
      for (int qx = 0; qx < im.width; ++qx) {
        const auto [ix, fx] = locate(qx, im.width, nx);
        const std::array<std::pair<int, double>, 4> corners = {
            std::pair{iy * nx + ix, (1 - fy) * (1 - fx)},
            std::pair{iy * nx + std::min(ix + 1, nx - 1), (1 - fy) * fx},
            std::pair{std::min(iy + 1, ny - 1) * nx + ix, fy * (1 - fx)},
            std::pair{std::min(iy + 1, ny - 1) * nx + std::min(ix + 1, nx - 1), fy * fx}};
        std::fill(h.begin(), h.end(), 0.f);
        for (const auto& [k, w] : corners) {
          if (w == 0) continue;
          const float* psf = psfs.data() + std::size_t(k) * s2;
          for (std::size_t i = 0; i < s2; ++i) h[i] += static_cast<float>(w) * psf[i];
        }
        const double v = xc[std::size_t(qy) * std::size_t(im.width) + std::size_t(qx)];
        for (int ty = 0; ty < s; ++ty) {
          const int py = qy + ty - half;
          if (py < 0 || py >= im.height) continue;
          for (int tx = 0; tx < s; ++tx) {
            const int px = qx + tx - half;
            if (px < 0 || px >= im.width) continue;
            const double hv = h[std::size_t(ty) * std::size_t(s) + std::size_t(tx)];
            const std::size_t at = std::size_t(py) * std::size_t(im.width) + std::size_t(px);
            acc[at] += v * hv;
            norm[at] += hv;
          }
        }
      }
    }
    float* yc = y.data() + std::size_t(ch) * hw;
    for (std::size_t i = 0; i < hw; ++i)
      yc[i] = norm[i] > 0 ? static_cast<float>(acc[i] / norm[i]) : 0.f;
    rep.image_seconds +=
        std::chrono::duration<double>(std::chrono::steady_clock::now() - t1).count();
  }
  return y;
}

}  // namespace vkjr2::sim
