#include <vkjr2/kernels/ref/fft_ref.hpp>

#include <cmath>
#include <numbers>

namespace vkjr2::ref {
namespace {

using cd = std::complex<double>;

std::int64_t smallest_factor(std::int64_t n) {
  for (std::int64_t f = 2; f * f <= n; ++f) {
    if (n % f == 0) return f;
  }
  return n;
}

// exp(sign · 2πi t / n), with t reduced mod n for accuracy.
cd root(std::int64_t t, std::int64_t n, int sign) {
  const double a = sign * 2.0 * std::numbers::pi * double(t % n) / double(n);
  return {std::cos(a), std::sin(a)};
}

// Out-of-place recursive decimation in time: n = f · m; f sub-DFTs of
// length m over x[f·i + s], combined by f-point DFTs with twiddles.
void fft_rec(const cd* x, std::int64_t n, std::int64_t stride, int sign, cd* out) {
  if (n == 1) {
    out[0] = x[0];
    return;
  }
  const std::int64_t f = smallest_factor(n);
  if (f == n) {  // prime: naive DFT
    for (std::int64_t k = 0; k < n; ++k) {
      cd acc = 0;
      for (std::int64_t j = 0; j < n; ++j) acc += x[j * stride] * root(j * k, n, sign);
      out[k] = acc;
    }
    return;
  }
  const std::int64_t m = n / f;
  std::vector<cd> sub(static_cast<std::size_t>(n));
  for (std::int64_t s = 0; s < f; ++s) fft_rec(x + s * stride, m, stride * f, sign, &sub[s * m]);
  // X[k1 + m k2] = Σ_s w_n^(s (k1 + m k2)) Sub_s[k1]
  for (std::int64_t k1 = 0; k1 < m; ++k1) {
    for (std::int64_t k2 = 0; k2 < f; ++k2) {
      const std::int64_t k = k1 + m * k2;
      cd acc = 0;
      for (std::int64_t s = 0; s < f; ++s) acc += sub[s * m + k1] * root(s * k, n, sign);
      out[k] = acc;
    }
  }
}

}  // namespace

void dft1d(std::complex<double>* data, std::int64_t n, std::int64_t stride, int sign) {
  std::vector<cd> in(static_cast<std::size_t>(n)), out(static_cast<std::size_t>(n));
  for (std::int64_t i = 0; i < n; ++i) in[i] = data[i * stride];
  fft_rec(in.data(), n, 1, sign, out.data());
  for (std::int64_t i = 0; i < n; ++i) data[i * stride] = out[i];
}

std::vector<double> fft2d_c2c(std::span<const float> x, std::int64_t batch, std::int64_t h,
                              std::int64_t w, bool inverse) {
  const int sign = inverse ? 1 : -1;
  std::vector<cd> a(std::size_t(batch * h * w));
  for (std::size_t i = 0; i < a.size(); ++i) a[i] = {x[2 * i], x[2 * i + 1]};
  for (std::int64_t b = 0; b < batch; ++b) {
    cd* img = &a[std::size_t(b * h * w)];
    for (std::int64_t y = 0; y < h; ++y) dft1d(img + y * w, w, 1, sign);
    for (std::int64_t c = 0; c < w; ++c) dft1d(img + c, h, w, sign);
  }
  std::vector<double> out(2 * a.size());
  for (std::size_t i = 0; i < a.size(); ++i) {
    out[2 * i] = a[i].real();
    out[2 * i + 1] = a[i].imag();
  }
  return out;
}

std::vector<double> fft2d_r2c(std::span<const float> x, std::int64_t batch, std::int64_t h,
                              std::int64_t w) {
  std::vector<float> complex_x(2 * x.size(), 0.f);
  for (std::size_t i = 0; i < x.size(); ++i) complex_x[2 * i] = x[i];
  const std::vector<double> full = fft2d_c2c(complex_x, batch, h, w, false);
  const std::int64_t half = w / 2 + 1;
  std::vector<double> out(std::size_t(2 * batch * h * half));
  for (std::int64_t r = 0; r < batch * h; ++r) {
    for (std::int64_t c = 0; c < half; ++c) {
      out[2 * (r * half + c)] = full[2 * (r * w + c)];
      out[2 * (r * half + c) + 1] = full[2 * (r * w + c) + 1];
    }
  }
  return out;
}

}  // namespace vkjr2::ref
