#include <vkjr2/kernels/ref/conv2d_ref.hpp>

#include <cstddef>

namespace vkjr2::ref {
namespace {

// Calls f(n, co, oy, ox, ci, c, ky, kx, x_index) for every in-image tap;
// c is ci's index inside its group (the weight's second axis).
template <class F>
void for_each_tap(const Conv2dDims& d, const kernels::Conv2dParams& p, F&& f) {
  const std::int64_t hout = conv2d_out_h(d, p), wout = conv2d_out_w(d, p);
  const std::int64_t cin_g = d.cin / p.groups, cout_g = d.cout / p.groups;
  for (std::int64_t n = 0; n < d.n; ++n) {
    for (std::int64_t co = 0; co < d.cout; ++co) {
      const std::int64_t g = co / cout_g;
      for (std::int64_t oy = 0; oy < hout; ++oy) {
        for (std::int64_t ox = 0; ox < wout; ++ox) {
          for (std::int64_t c = 0; c < cin_g; ++c) {
            const std::int64_t ci = g * cin_g + c;
            for (std::int64_t ky = 0; ky < d.kh; ++ky) {
              const std::int64_t iy = oy * p.stride_y - p.pad.top + ky * p.dilation_y;
              if (iy < 0 || iy >= d.h) continue;
              for (std::int64_t kx = 0; kx < d.kw; ++kx) {
                const std::int64_t ix = ox * p.stride_x - p.pad.left + kx * p.dilation_x;
                if (ix < 0 || ix >= d.w) continue;
                const std::size_t yi = std::size_t(((n * d.cout + co) * hout + oy) * wout + ox);
                const std::size_t wi = std::size_t(((co * cin_g + c) * d.kh + ky) * d.kw + kx);
                const std::size_t xi = std::size_t(((n * d.cin + ci) * d.h + iy) * d.w + ix);
                f(yi, wi, xi);
              }
            }
          }
        }
      }
    }
  }
}

}  // namespace

std::int64_t conv2d_out_h(const Conv2dDims& d, const kernels::Conv2dParams& p) {
  return (d.h + p.pad.top + p.pad.bottom - ((d.kh - 1) * p.dilation_y + 1)) / p.stride_y + 1;
}

std::int64_t conv2d_out_w(const Conv2dDims& d, const kernels::Conv2dParams& p) {
  return (d.w + p.pad.left + p.pad.right - ((d.kw - 1) * p.dilation_x + 1)) / p.stride_x + 1;
}

std::vector<float> conv2d(std::span<const float> x, std::span<const float> w,
                          std::span<const float> bias, const Conv2dDims& d,
                          const kernels::Conv2dParams& p, std::span<const float> residual,
                          std::int64_t cres) {
  const std::int64_t hw = conv2d_out_h(d, p) * conv2d_out_w(d, p);
  std::vector<double> acc(std::size_t(d.n * d.cout * hw), 0.0);
  for_each_tap(d, p, [&](std::size_t yi, std::size_t wi, std::size_t xi) {
    const double xv = p.relu_input && x[xi] < 0 ? 0.0 : double(x[xi]);
    acc[yi] += double(w[wi]) * xv;
  });
  std::vector<float> y(acc.size());
  for (std::size_t i = 0; i < acc.size(); ++i) {
    double v = acc[i];
    const std::size_t co = (i / std::size_t(hw)) % std::size_t(d.cout);
    if (!bias.empty()) v += bias[co];
    if (!residual.empty() && co < std::size_t(cres)) {
      const std::size_t n = i / (std::size_t(hw) * std::size_t(d.cout));
      v += residual[(n * std::size_t(cres) + co) * std::size_t(hw) + i % std::size_t(hw)];
    }
    if (p.activation == kernels::Activation::relu && v < 0) v = 0;
    if (p.activation == kernels::Activation::leaky_relu && v < 0) v *= p.leaky_slope;
    y[i] = float(v);
  }
  return y;
}

std::vector<float> conv2d_backward_data(std::span<const float> dy, std::span<const float> w,
                                        const Conv2dDims& d, const kernels::Conv2dParams& p) {
  std::vector<double> acc(std::size_t(d.n * d.cin * d.h * d.w), 0.0);
  for_each_tap(d, p, [&](std::size_t yi, std::size_t wi, std::size_t xi) {
    acc[xi] += double(w[wi]) * double(dy[yi]);
  });
  return std::vector<float>(acc.begin(), acc.end());
}

std::vector<float> conv2d_backward_weight(std::span<const float> x, std::span<const float> dy,
                                          const Conv2dDims& d, const kernels::Conv2dParams& p) {
  std::vector<double> acc(std::size_t(d.cout * (d.cin / p.groups) * d.kh * d.kw), 0.0);
  for_each_tap(d, p, [&](std::size_t yi, std::size_t wi, std::size_t xi) {
    acc[wi] += double(x[xi]) * double(dy[yi]);
  });
  return std::vector<float>(acc.begin(), acc.end());
}

std::vector<float> conv2d_backward_bias(std::span<const float> dy, const Conv2dDims& d,
                                        const kernels::Conv2dParams& p) {
  const std::size_t hw = std::size_t(conv2d_out_h(d, p) * conv2d_out_w(d, p));
  std::vector<double> acc(std::size_t(d.cout), 0.0);
  for (std::size_t i = 0; i < dy.size(); ++i) acc[(i / hw) % std::size_t(d.cout)] += dy[i];
  return std::vector<float>(acc.begin(), acc.end());
}

}  // namespace vkjr2::ref
