#include <vkjr2/kernels/ref/grid_sample_ref.hpp>

#include <cmath>
#include <cstddef>

namespace vkjr2::ref {
namespace {

using kernels::SamplePadding;

// PyTorch clip_coordinates_set_grad: clamp to [0, size-1], gradient 0 where clamped.
double clip(double x, int size, double& grad) {
  if (x <= 0) {
    grad = 0;
    return 0;
  }
  if (x >= size - 1) {
    grad = 0;
    return size - 1;
  }
  grad = 1;
  return x;
}

// Bilinear corners and weights of one position (PyTorch's nw/ne/sw/se).
struct Corners {
  int x_w, y_n;  // north-west tap
  double ix, iy, gx_mult, gy_mult;
};

Corners corners(double ix, double iy, int in_w, int in_h, SamplePadding padding) {
  Corners c{};
  c.gx_mult = c.gy_mult = 1;
  if (padding == SamplePadding::border) {
    ix = clip(ix, in_w, c.gx_mult);
    iy = clip(iy, in_h, c.gy_mult);
  }
  c.ix = ix;
  c.iy = iy;
  c.x_w = static_cast<int>(std::floor(ix));
  c.y_n = static_cast<int>(std::floor(iy));
  return c;
}

// PyTorch grid_sampler_unnormalize, in float as its fp32 kernel computes it
// (so the reference and the device agree on which cell a position falls in).
double unnormalize(float g, int size, bool align_corners, double& scale) {
  const float s = static_cast<float>(size);
  if (align_corners) {
    scale = (size - 1) / 2.0;
    return double((g + 1.f) / 2.f * (s - 1.f));
  }
  scale = size / 2.0;
  return double(((g + 1.f) * s - 1.f) / 2.f);
}

std::vector<double> grid_to_pixels(std::span<const float> grid, const SampleDims& d,
                                   bool align_corners, std::vector<double>& scale) {
  std::vector<double> pos(grid.size());
  scale.resize(grid.size());
  for (std::size_t i = 0; i < grid.size(); i += 2) {
    pos[i] = unnormalize(grid[i], d.in_w, align_corners, scale[i]);
    pos[i + 1] = unnormalize(grid[i + 1], d.in_h, align_corners, scale[i + 1]);
  }
  return pos;
}

double base_coord(int i, int size, bool align_corners) {
  if (size <= 1) return 0;
  const double lin = -1 + 2.0 * i / (size - 1);
  return align_corners ? lin : lin * (size - 1) / size;
}

}  // namespace

std::vector<float> sample_pixels(std::span<const float> img, std::span<const double> pos,
                                 const SampleDims& d, SamplePadding padding) {
  const std::size_t plane_in = std::size_t(d.in_h) * d.in_w;
  const std::size_t plane_out = std::size_t(d.out_h) * d.out_w;
  std::vector<float> out(std::size_t(d.n) * d.c * plane_out);
  auto inside = [&](int x, int y) { return x >= 0 && x < d.in_w && y >= 0 && y < d.in_h; };
  for (int n = 0; n < d.n; ++n) {
    for (std::size_t p = 0; p < plane_out; ++p) {
      const std::size_t pi = (n * plane_out + p) * 2;
      const Corners k = corners(pos[pi], pos[pi + 1], d.in_w, d.in_h, padding);
      const int xw = k.x_w, xe = k.x_w + 1, yn = k.y_n, ys = k.y_n + 1;
      const double nw = (xe - k.ix) * (ys - k.iy), ne = (k.ix - xw) * (ys - k.iy);
      const double sw = (xe - k.ix) * (k.iy - yn), se = (k.ix - xw) * (k.iy - yn);
      for (int c = 0; c < d.c; ++c) {
        const float* plane = img.data() + (std::size_t(n) * d.c + c) * plane_in;
        auto at = [&](int x, int y) { return double(plane[std::size_t(y) * d.in_w + x]); };
        double v = 0;
        if (inside(xw, yn)) v += at(xw, yn) * nw;
        if (inside(xe, yn)) v += at(xe, yn) * ne;
        if (inside(xw, ys)) v += at(xw, ys) * sw;
        if (inside(xe, ys)) v += at(xe, ys) * se;
        out[(std::size_t(n) * d.c + c) * plane_out + p] = static_cast<float>(v);
      }
    }
  }
  return out;
}

void sample_pixels_backward(std::span<const float> img, std::span<const double> pos,
                            std::span<const float> d_out, const SampleDims& d,
                            SamplePadding padding, std::vector<float>& d_img,
                            std::vector<double>& d_pos) {
  const std::size_t plane_in = std::size_t(d.in_h) * d.in_w;
  const std::size_t plane_out = std::size_t(d.out_h) * d.out_w;
  std::vector<double> acc(std::size_t(d.n) * d.c * plane_in, 0.0);
  d_pos.assign(std::size_t(d.n) * plane_out * 2, 0.0);
  auto inside = [&](int x, int y) { return x >= 0 && x < d.in_w && y >= 0 && y < d.in_h; };
  for (int n = 0; n < d.n; ++n) {
    for (std::size_t p = 0; p < plane_out; ++p) {
      const std::size_t pi = (n * plane_out + p) * 2;
      const Corners k = corners(pos[pi], pos[pi + 1], d.in_w, d.in_h, padding);
      const int xw = k.x_w, xe = k.x_w + 1, yn = k.y_n, ys = k.y_n + 1;
      const double nw = (xe - k.ix) * (ys - k.iy), ne = (k.ix - xw) * (ys - k.iy);
      const double sw = (xe - k.ix) * (k.iy - yn), se = (k.ix - xw) * (k.iy - yn);
      double gix = 0, giy = 0;
      for (int c = 0; c < d.c; ++c) {
        const std::size_t base = (std::size_t(n) * d.c + c) * plane_in;
        const double g = d_out[(std::size_t(n) * d.c + c) * plane_out + p];
        auto idx = [&](int x, int y) { return base + std::size_t(y) * d.in_w + x; };
        if (inside(xw, yn)) {
          const double v = img[idx(xw, yn)];
          acc[idx(xw, yn)] += nw * g;
          gix -= v * (ys - k.iy) * g;
          giy -= v * (xe - k.ix) * g;
        }
        if (inside(xe, yn)) {
          const double v = img[idx(xe, yn)];
          acc[idx(xe, yn)] += ne * g;
          gix += v * (ys - k.iy) * g;
          giy -= v * (k.ix - xw) * g;
        }
        if (inside(xw, ys)) {
          const double v = img[idx(xw, ys)];
          acc[idx(xw, ys)] += sw * g;
          gix -= v * (k.iy - yn) * g;
          giy += v * (xe - k.ix) * g;
        }
        if (inside(xe, ys)) {
          const double v = img[idx(xe, ys)];
          acc[idx(xe, ys)] += se * g;
          gix += v * (k.iy - yn) * g;
          giy += v * (k.ix - xw) * g;
        }
      }
      d_pos[pi] = gix * k.gx_mult;
      d_pos[pi + 1] = giy * k.gy_mult;
    }
  }
  d_img.assign(acc.begin(), acc.end());
}

std::vector<float> grid_sample(std::span<const float> input, std::span<const float> grid,
                               const SampleDims& d, kernels::GridSampleOptions options) {
  std::vector<double> scale;
  const std::vector<double> pos = grid_to_pixels(grid, d, options.align_corners, scale);
  return sample_pixels(input, pos, d, options.padding);
}

void grid_sample_backward(std::span<const float> input, std::span<const float> grid,
                          std::span<const float> d_out, const SampleDims& d,
                          kernels::GridSampleOptions options, std::vector<float>& d_input,
                          std::vector<float>& d_grid) {
  std::vector<double> scale;
  const std::vector<double> pos = grid_to_pixels(grid, d, options.align_corners, scale);
  std::vector<double> d_pos;
  sample_pixels_backward(input, pos, d_out, d, options.padding, d_input, d_pos);
  d_grid.resize(d_pos.size());
  for (std::size_t i = 0; i < d_pos.size(); ++i) {
    d_grid[i] = static_cast<float>(d_pos[i] * scale[i]);
  }
}

std::vector<float> affine_grid(std::span<const float> theta, int n, int h, int w,
                               bool align_corners) {
  std::vector<float> grid(std::size_t(n) * h * w * 2);
  for (int b = 0; b < n; ++b) {
    const float* t = theta.data() + 6 * b;
    for (int y = 0; y < h; ++y) {
      for (int x = 0; x < w; ++x) {
        const double bx = base_coord(x, w, align_corners), by = base_coord(y, h, align_corners);
        const std::size_t o = ((std::size_t(b) * h + y) * w + x) * 2;
        grid[o] = static_cast<float>(t[0] * bx + t[1] * by + t[2]);
        grid[o + 1] = static_cast<float>(t[3] * bx + t[4] * by + t[5]);
      }
    }
  }
  return grid;
}

std::vector<float> affine_grid_backward(std::span<const float> d_grid, int n, int h, int w,
                                        bool align_corners) {
  std::vector<float> d_theta(std::size_t(n) * 6);
  for (int b = 0; b < n; ++b) {
    double s[6] = {0, 0, 0, 0, 0, 0};
    for (int y = 0; y < h; ++y) {
      for (int x = 0; x < w; ++x) {
        const double bx = base_coord(x, w, align_corners), by = base_coord(y, h, align_corners);
        const std::size_t o = ((std::size_t(b) * h + y) * w + x) * 2;
        const double gx = d_grid[o], gy = d_grid[o + 1];
        s[0] += gx * bx;
        s[1] += gx * by;
        s[2] += gx;
        s[3] += gy * bx;
        s[4] += gy * by;
        s[5] += gy;
      }
    }
    for (int k = 0; k < 6; ++k) d_theta[6 * b + k] = static_cast<float>(s[k]);
  }
  return d_theta;
}

}  // namespace vkjr2::ref
