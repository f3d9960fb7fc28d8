#include <vkjr2/kernels/ref/flow_ref.hpp>
#include <vkjr2/kernels/ref/warp_ref.hpp>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstddef>

namespace vkjr2::ref {

LucasKanadeResult lucas_kanade_step(std::span<const float> ref, int ref_images,
                                    std::span<const float> img, std::span<const float> flow, int n,
                                    int h, int w, const kernels::LucasKanade& p) {
  const std::size_t plane = std::size_t(h) * w;
  const std::vector<float> warped = warp(img, flow, n, 1, h, w, kernels::SamplePadding::border);
  // The five terms per pixel, zero where the sample lies outside the image.
  std::vector<std::array<double, 5>> terms(std::size_t(n) * plane);
  for (int b = 0; b < n; ++b) {
    const float* r = ref.data() + (ref_images == 1 ? 0 : std::size_t(b) * plane);
    for (int y = 0; y < h; ++y) {
      for (int x = 0; x < w; ++x) {
        const auto at = [&](int yy, int xx) { return double(r[std::size_t(yy) * w + xx]); };
        const double gx = 0.5 * (at(y, std::min(x + 1, w - 1)) - at(y, std::max(x - 1, 0)));
        const double gy = 0.5 * (at(std::min(y + 1, h - 1), x) - at(std::max(y - 1, 0), x));
        const std::size_t pix = std::size_t(y) * w + x;
        const std::size_t i = b * plane + pix;
        // The position in float, as the device forms it.
        const float px = float(x) + flow[2 * b * plane + pix];
        const float py = float(y) + flow[(2 * b + 1) * plane + pix];
        const bool inside = px >= 0.f && px <= float(w - 1) && py >= 0.f && py <= float(h - 1);
        const double e = double(warped[i]) - at(y, x);
        terms[i] = inside ? std::array<double, 5>{gx * gx, gx * gy, gy * gy, gx * e, gy * e}
                          : std::array<double, 5>{};
      }
    }
  }
  // Box means of 2r + 1 taps inside the image: twice along x, twice along y.
  const auto box = [&](bool along_x) {
    std::vector<std::array<double, 5>> next(terms.size());
    for (int b = 0; b < n; ++b) {
      for (int y = 0; y < h; ++y) {
        for (int x = 0; x < w; ++x) {
          const int c = along_x ? x : y, size = along_x ? w : h;
          const int lo = std::max(c - p.radius, 0), hi = std::min(c + p.radius, size - 1);
          std::array<double, 5> s{};
          for (int j = lo; j <= hi; ++j) {
            const auto& t =
                terms[b * plane + (along_x ? std::size_t(y) * w + j : std::size_t(j) * w + x)];
            for (std::size_t k = 0; k < 5; ++k) s[k] += t[k];
          }
          for (double& v : s) v /= double(hi - lo + 1);
          next[b * plane + std::size_t(y) * w + x] = s;
        }
      }
    }
    terms.swap(next);
  };
  box(true);
  box(true);
  box(false);
  box(false);
  LucasKanadeResult out;
  out.flow.resize(std::size_t(n) * 2 * plane);
  out.min_eig.resize(std::size_t(n) * plane);
  for (int b = 0; b < n; ++b) {
    for (std::size_t pix = 0; pix < plane; ++pix) {
      const auto [a, c, d, bx, by] = terms[b * plane + pix];
      const double half_diff = 0.5 * (a - d);
      const double lmin = 0.5 * (a + d) - std::sqrt(half_diff * half_diff + c * c);
      double dx = flow[2 * b * plane + pix], dy = flow[(2 * b + 1) * plane + pix];
      if (lmin >= double(p.min_eigenvalue)) {
        const double det = a * d - c * c;
        dx -= (d * bx - c * by) / det;
        dy -= (a * by - c * bx) / det;
      }
      out.flow[2 * b * plane + pix] = dx;
      out.flow[(2 * b + 1) * plane + pix] = dy;
      out.min_eig[b * plane + pix] = lmin;
    }
  }
  return out;
}

}  // namespace vkjr2::ref
