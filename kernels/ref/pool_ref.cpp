#include <vkjr2/kernels/ref/pool_ref.hpp>

#include <algorithm>
#include <cmath>

namespace vkjr2::ref {
namespace {

std::int64_t out_len(std::int64_t in, int k, int s, int before, int after) {
  return (in + before + after - k) / s + 1;
}

// Divisor of the window starting at s0 (see kernels/pool.hpp).
std::int64_t extent(std::int64_t s0, int k, std::int64_t n, int after, bool include_pad) {
  if (include_pad) return std::min<std::int64_t>(s0 + k, n + after) - s0;
  return std::min<std::int64_t>(s0 + k, n) - std::max<std::int64_t>(s0, 0);
}

}  // namespace

PoolResult max_pool2d(std::span<const float> x, std::int64_t planes, std::int64_t h, std::int64_t w,
                      const kernels::Pool2d& p) {
  PoolResult r;
  r.oh = out_len(h, p.kernel_h, p.stride_h, p.pad_top, p.pad_bottom);
  r.ow = out_len(w, p.kernel_w, p.stride_w, p.pad_left, p.pad_right);
  r.y.resize(std::size_t(planes * r.oh * r.ow));
  r.indices.resize(r.y.size());
  for (std::int64_t pl = 0; pl < planes; ++pl) {
    for (std::int64_t oy = 0; oy < r.oh; ++oy) {
      for (std::int64_t ox = 0; ox < r.ow; ++ox) {
        float best = 0;
        std::int64_t best_i = -1;
        for (std::int64_t ky = 0; ky < p.kernel_h; ++ky) {
          const std::int64_t iy = oy * p.stride_h - p.pad_top + ky;
          if (iy < 0 || iy >= h) continue;
          for (std::int64_t kx = 0; kx < p.kernel_w; ++kx) {
            const std::int64_t ix = ox * p.stride_w - p.pad_left + kx;
            if (ix < 0 || ix >= w) continue;
            const float v = x[std::size_t((pl * h + iy) * w + ix)];
            if (best_i < 0 || v > best || std::isnan(v)) {
              best = v;
              best_i = iy * w + ix;
            }
          }
        }
        const std::size_t o = std::size_t((pl * r.oh + oy) * r.ow + ox);
        r.y[o] = best;
        r.indices[o] = static_cast<std::int32_t>(best_i);
      }
    }
  }
  return r;
}

std::vector<float> max_pool2d_backward(std::span<const float> dy,
                                       std::span<const std::int32_t> indices, std::int64_t planes,
                                       std::int64_t h, std::int64_t w, const kernels::Pool2d& p) {
  const std::int64_t oh = out_len(h, p.kernel_h, p.stride_h, p.pad_top, p.pad_bottom);
  const std::int64_t ow = out_len(w, p.kernel_w, p.stride_w, p.pad_left, p.pad_right);
  std::vector<double> acc(std::size_t(planes * h * w), 0.0);
  for (std::int64_t pl = 0; pl < planes; ++pl) {
    for (std::int64_t o = 0; o < oh * ow; ++o) {
      const std::size_t oi = std::size_t(pl * oh * ow + o);
      acc[std::size_t(pl * h * w + indices[oi])] += dy[oi];
    }
  }
  return {acc.begin(), acc.end()};
}

PoolResult avg_pool2d(std::span<const float> x, std::int64_t planes, std::int64_t h, std::int64_t w,
                      const kernels::Pool2d& p, bool count_include_pad) {
  PoolResult r;
  r.oh = out_len(h, p.kernel_h, p.stride_h, p.pad_top, p.pad_bottom);
  r.ow = out_len(w, p.kernel_w, p.stride_w, p.pad_left, p.pad_right);
  r.y.resize(std::size_t(planes * r.oh * r.ow));
  for (std::int64_t pl = 0; pl < planes; ++pl) {
    for (std::int64_t oy = 0; oy < r.oh; ++oy) {
      const std::int64_t ys = oy * p.stride_h - p.pad_top;
      for (std::int64_t ox = 0; ox < r.ow; ++ox) {
        const std::int64_t xs = ox * p.stride_w - p.pad_left;
        double s = 0;
        for (std::int64_t iy = std::max<std::int64_t>(ys, 0);
             iy < std::min<std::int64_t>(ys + p.kernel_h, h); ++iy) {
          for (std::int64_t ix = std::max<std::int64_t>(xs, 0);
               ix < std::min<std::int64_t>(xs + p.kernel_w, w); ++ix) {
            s += x[std::size_t((pl * h + iy) * w + ix)];
          }
        }
        const std::int64_t count = extent(ys, p.kernel_h, h, p.pad_bottom, count_include_pad) *
                                   extent(xs, p.kernel_w, w, p.pad_right, count_include_pad);
        r.y[std::size_t((pl * r.oh + oy) * r.ow + ox)] = static_cast<float>(s / double(count));
      }
    }
  }
  return r;
}

std::vector<float> avg_pool2d_backward(std::span<const float> dy, std::int64_t planes,
                                       std::int64_t h, std::int64_t w, const kernels::Pool2d& p,
                                       bool count_include_pad) {
  const std::int64_t oh = out_len(h, p.kernel_h, p.stride_h, p.pad_top, p.pad_bottom);
  const std::int64_t ow = out_len(w, p.kernel_w, p.stride_w, p.pad_left, p.pad_right);
  std::vector<double> acc(std::size_t(planes * h * w), 0.0);
  for (std::int64_t pl = 0; pl < planes; ++pl) {
    for (std::int64_t oy = 0; oy < oh; ++oy) {
      const std::int64_t ys = oy * p.stride_h - p.pad_top;
      for (std::int64_t ox = 0; ox < ow; ++ox) {
        const std::int64_t xs = ox * p.stride_w - p.pad_left;
        const std::int64_t count = extent(ys, p.kernel_h, h, p.pad_bottom, count_include_pad) *
                                   extent(xs, p.kernel_w, w, p.pad_right, count_include_pad);
        const double g = dy[std::size_t((pl * oh + oy) * ow + ox)] / double(count);
        for (std::int64_t iy = std::max<std::int64_t>(ys, 0);
             iy < std::min<std::int64_t>(ys + p.kernel_h, h); ++iy) {
          for (std::int64_t ix = std::max<std::int64_t>(xs, 0);
               ix < std::min<std::int64_t>(xs + p.kernel_w, w); ++ix) {
            acc[std::size_t((pl * h + iy) * w + ix)] += g;
          }
        }
      }
    }
  }
  return {acc.begin(), acc.end()};
}

std::vector<float> global_avg_pool(std::span<const float> x, std::int64_t planes, std::int64_t hw) {
  std::vector<float> y(static_cast<std::size_t>(planes));
  for (std::int64_t pl = 0; pl < planes; ++pl) {
    double s = 0;
    for (std::int64_t i = 0; i < hw; ++i) s += x[std::size_t(pl * hw + i)];
    y[std::size_t(pl)] = static_cast<float>(s / double(hw));
  }
  return y;
}

}  // namespace vkjr2::ref
