#include <vkjr2/kernels/ref/elementwise_ref.hpp>

#include <cmath>
#include <cstddef>

namespace vkjr2::ref {

std::vector<float> unary(Unary op, std::span<const float> x, float p0, float p1) {
  std::vector<float> y(x.size());
  for (std::size_t i = 0; i < x.size(); ++i) {
    const float v = x[i];
    switch (op) {
      case Unary::scale_shift:
        y[i] = p0 * v + p1;
        break;
      case Unary::exp:
        y[i] = std::exp(v);
        break;
      case Unary::log:
        y[i] = std::log(v);
        break;
      case Unary::relu:
        y[i] = v < 0 ? 0.f : v;
        break;
      case Unary::leaky_relu:
        y[i] = v < 0 ? v * p0 : v;
        break;
      case Unary::sigmoid:
        y[i] = float(1.0 / (1.0 + std::exp(-double(v))));
        break;
      case Unary::tanh:
        y[i] = std::tanh(v);
        break;
    }
  }
  return y;
}

std::vector<float> unary_backward(Unary op, std::span<const float> s, std::span<const float> dy,
                                  float p0) {
  std::vector<float> dx(s.size());
  for (std::size_t i = 0; i < s.size(); ++i) {
    const float v = s[i], g = dy[i];
    switch (op) {
      case Unary::scale_shift:
        dx[i] = g * p0;
        break;
      case Unary::exp:
        dx[i] = g * v;
        break;
      case Unary::log:
        dx[i] = g / v;
        break;
      case Unary::relu:
        dx[i] = v > 0 ? g : 0.f;
        break;
      case Unary::leaky_relu:
        dx[i] = v > 0 ? g : g * p0;
        break;
      case Unary::sigmoid:
        dx[i] = g * v * (1 - v);
        break;
      case Unary::tanh:
        dx[i] = g * (1 - v * v);
        break;
    }
  }
  return dx;
}

std::vector<float> binary(int op, std::span<const float> a, std::span<const float> b,
                          std::uint32_t channels, std::uint32_t hw) {
  std::vector<float> out(a.size());
  for (std::size_t i = 0; i < a.size(); ++i) {
    const float v = channels > 0 ? b[(i / hw) % channels] : b[i];
    out[i] = op == 0 ? a[i] + v : (op == 1 ? a[i] - v : a[i] * v);
  }
  return out;
}

std::vector<float> prelu(std::span<const float> x, std::span<const float> slope,
                         std::uint32_t channels, std::uint32_t hw) {
  std::vector<float> y(x.size());
  for (std::size_t i = 0; i < x.size(); ++i) {
    y[i] = x[i] < 0 ? x[i] * slope[(i / hw) % channels] : x[i];
  }
  return y;
}

void prelu_backward(std::span<const float> x, std::span<const float> slope,
                    std::span<const float> dy, std::uint32_t channels, std::uint32_t hw,
                    std::vector<float>& dx, std::vector<float>& dslope) {
  dx.assign(x.size(), 0.f);
  std::vector<double> acc(channels, 0.0);
  for (std::size_t i = 0; i < x.size(); ++i) {
    const std::size_t c = (i / hw) % channels;
    dx[i] = x[i] > 0 ? dy[i] : dy[i] * slope[c];
    acc[c] += double(dy[i]) * std::fmin(x[i], 0.f);
  }
  dslope.assign(acc.begin(), acc.end());
}

std::vector<float> simple_gate(std::span<const float> x, std::uint32_t batch,
                               std::uint32_t channels, std::uint32_t hw) {
  const std::size_t half = std::size_t(channels) * hw;
  std::vector<float> y(batch * half);
  for (std::size_t n = 0; n < batch; ++n) {
    for (std::size_t i = 0; i < half; ++i)
      y[n * half + i] = x[2 * n * half + i] * x[(2 * n + 1) * half + i];
  }
  return y;
}

std::vector<float> simple_gate_backward(std::span<const float> x, std::span<const float> dy,
                                        std::uint32_t batch, std::uint32_t channels,
                                        std::uint32_t hw) {
  const std::size_t half = std::size_t(channels) * hw;
  std::vector<float> dx(x.size());
  for (std::size_t n = 0; n < batch; ++n) {
    for (std::size_t i = 0; i < half; ++i) {
      const std::size_t a = 2 * n * half + i, b = a + half;
      dx[a] = dy[n * half + i] * x[b];
      dx[b] = dy[n * half + i] * x[a];
    }
  }
  return dx;
}

std::vector<float> channel_sum(std::span<const float> a, std::span<const float> b,
                               std::uint32_t channels, std::uint32_t hw) {
  std::vector<double> acc(channels, 0.0);
  for (std::size_t i = 0; i < a.size(); ++i) {
    acc[(i / hw) % channels] += double(a[i]) * (b.empty() ? 1.0 : double(b[i]));
  }
  return {acc.begin(), acc.end()};
}

}  // namespace vkjr2::ref
