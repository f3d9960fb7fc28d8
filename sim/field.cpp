#include <vkjr2/kernels/elementwise.hpp>
#include <vkjr2/kernels/mix.hpp>
#include <vkjr2/kernels/random.hpp>
#include <vkjr2/runtime/error.hpp>
#include <vkjr2/sim/field.hpp>
#include <vkjr2/sim/noll.hpp>
#include <vkjr2/sim/tilt.hpp>

#include <algorithm>
#include <cmath>
#include <string>
#include <vector>

namespace vkjr2::sim {
namespace {

int grid_points(int pixels, double step) {
  return pixels <= 1 ? 1 : static_cast<int>(std::ceil((pixels - 1) / step)) + 1;
}

// Signed lag of torus index i on a torus of n.
double lag(std::int64_t i, std::int64_t n) { return double(i <= n / 2 ? i : i - n); }

}  // namespace

TurbulenceField::~TurbulenceField() = default;

TurbulenceField::TurbulenceField(const Device& device, const Params& params,
                                 const FieldOptions& options)
    : device_(device),
      j_max_(options.j_max == 0 ? params.zernike_modes : options.j_max),
      batch_(params.image.batch),
      options_(options) {
  const char* op = "TurbulenceField";
  if (j_max_ < 3 || j_max_ > params.zernike_modes) {
    throw InvalidArgument(op, "FieldOptions::j_max must be 0 or in 3.." +
                                  std::to_string(params.zernike_modes) + ", got " +
                                  std::to_string(options.j_max));
  }
  if (options.max_step_px < 1 || options.max_step_px > 256) {
    throw InvalidArgument(
        op, "max_step_px must be in 1..256, got " + std::to_string(options.max_step_px));
  }
  if (!(options.min_step_correlation > 0 && options.min_step_correlation < 1)) {
    throw InvalidArgument(op, "min_step_correlation must be in (0, 1)");
  }
  for (double rho : {options.tilt_rho, options.high_order_rho}) {
    if (!(rho >= 0 && rho < 1)) {
      throw InvalidArgument(
          op, "frame-to-frame correlations (tilt_rho, high_order_rho) must be in [0, 1), got " +
                  std::to_string(rho));
    }
  }
  const Derived derived = derive(params);
  const int height = params.image.height, width = params.image.width;
  const double ifov = ifov_rad_ = derived.ifov_rad;
  // Lags up to half the torus (2× the grid) plus the FFT-length round-up.
  correlation_ = std::make_unique<FieldCorrelation>(params, j_max_,
                                                    (1.3 * std::hypot(height, width) + 32) * ifov);
  // The grid step: as coarse as every mode's correlation allows.
  int step = 1;
  for (int g = options.max_step_px; g >= 1; --g) {
    bool ok = true;
    for (int j = 2; j <= j_max_ && ok; ++j) {
      ok = (*correlation_)(j, g * ifov, 0) >= options.min_step_correlation &&
           (*correlation_)(j, 0, g * ifov) >= options.min_step_correlation;
    }
    if (ok) {
      step = g;
      break;
    }
  }
  grid_h_ = grid_points(height, step);
  grid_w_ = grid_points(width, step);
  step_y_ = grid_h_ > 1 ? double(height - 1) / (grid_h_ - 1) : 0.0;
  step_x_ = grid_w_ > 1 ? double(width - 1) / (grid_w_ - 1) : 0.0;
  // Circulant embedding on a torus 2× the grid. The tilts' correlation
  // decays slowly (∝ s^(−1/3)), so part of the eigenvalue mass comes out
  // negative (≈ 3 % for the presets; a 4× torus only brought 3.6 % to 2.6 %
  // at 4× the cost) and is clipped, and each mode is rescaled to unit variance.
  const std::int64_t k_modes = modes();
  const std::int64_t planes = k_modes * batch_;
  torus_h_ = static_cast<int>(kernels::fft_next_length(std::max(2, 2 * (grid_h_ - 1))));
  torus_w_ = static_cast<int>(kernels::fft_next_length(std::max(2, 2 * (grid_w_ - 1))));
  const std::vector<float> eig = embedding_eigenvalues();
  const std::int64_t mh = torus_h_, mw = torus_w_, m = mh * mw;
  std::vector<float> spectrum(std::size_t(planes * m * 2));
  clipped_ = 0;
  for (std::int64_t k = 0; k < k_modes; ++k) {
    double positive = 0, negative = 0;
    for (std::int64_t i = 0; i < m; ++i) {
      const double v = eig[std::size_t((k * m + i) * 2)];
      (v > 0 ? positive : negative) += std::fabs(v);
    }
    clipped_ = std::max(clipped_, negative / std::max(positive + negative, 1e-300));
    // Clipping raises the variance above 1; rescale so that c(0) stays 1.
    const double renorm = positive > 0 ? double(m) / positive : 0.0;
    for (std::int64_t i = 0; i < m; ++i) {
      const double v = std::max(0.0, double(eig[std::size_t((k * m + i) * 2)]));
      const auto amp = static_cast<float>(std::sqrt(v * renorm / double(m)));
      for (std::int64_t b = 0; b < batch_; ++b) {
        const std::size_t at = std::size_t(((k * batch_ + b) * m + i) * 2);
        spectrum[at] = spectrum[at + 1] = amp;
      }
    }
  }
  spectrum_ = Tensor::from(device_, {planes, mh, mw, 2}, spectrum);
  seeds_ = Tensor::empty(device_, {planes, mh, mw, 2});
  planes_ = Tensor::empty(device_, {planes, mh, mw, 2});
  plan_ = std::make_unique<kernels::FftPlan>(device_, Shape{planes, mh, mw}, kernels::FftKind::c2c,
                                             kernels::FftNorm::none);

  const NollSampler noll(j_max_);
  std::vector<float> chol(noll.cholesky_factor().begin(), noll.cholesky_factor().end());
  mix_ = Tensor::from(device_, {k_modes, k_modes}, chol);
  scale_ = static_cast<float>(std::pow(derived.channels[0].d_over_r0, 5.0 / 6.0));
  tilt_x_ = tilt_y_ = static_cast<float>(sim::tilt_px(1.0, params, 0));
  coefficients_ = Tensor::empty(device_, {batch_, k_modes, grid_h_, grid_w_});
  tilt_ = Tensor::empty(device_, {batch_, 2, grid_h_, grid_w_});
}

std::vector<float> TurbulenceField::embedding_eigenvalues() const {
  const std::int64_t k_modes = modes(), mh = torus_h_, mw = torus_w_;
  const double ifov = ifov_rad_;
  std::vector<float> torus(std::size_t(k_modes * mh * mw * 2), 0.f);
  for (std::int64_t k = 0; k < k_modes; ++k) {
    // An uncorrelated mode is a delta at lag 0: a flat (white) spectrum.
    const bool white = k >= 2 && !options_.correlate_high_order;
    for (std::int64_t r = 0; r < mh; ++r) {
      for (std::int64_t c = 0; c < mw; ++c) {
        const double dy = lag(r, mh) * step_y_ * ifov, dx = lag(c, mw) * step_x_ * ifov;
        const double rho = white ? (r == 0 && c == 0 ? 1.0 : 0.0)
                                 : (*correlation_)(static_cast<int>(k) + 2, dx, dy);
        torus[std::size_t(((k * mh + r) * mw + c) * 2)] = static_cast<float>(rho);
      }
    }
  }
  kernels::fft2_host(device_, {k_modes, mh, mw}, torus, /*inverse=*/false, kernels::FftNorm::none);
  return torus;
}

void TurbulenceField::reset(std::uint64_t seed) {
  seed_ = seed;
  frame_ = -1;
  seeded_ = true;
}

void TurbulenceField::next(Stream& stream) {
  if (!seeded_) throw InvalidArgument("TurbulenceField::next", "call reset(seed) first");
  ++frame_;
  const std::int64_t plane = std::int64_t(torus_h_) * torus_w_ * 2;
  if (frame_ == 0) {
    kernels::randn(stream, seeds_, seed_, 0);
  } else {
    // Stream ids 2t − 1 and 2t for frame t: never reused within a sequence.
    const auto id = static_cast<std::uint32_t>(2 * frame_);
    const std::int64_t tilt_planes = 2 * std::int64_t(batch_);
    kernels::randn_ar1(stream, seeds_.view(Shape{tilt_planes * plane}), float(options_.tilt_rho),
                       seed_, id - 1);
    const std::int64_t rest = seeds_.numel() - tilt_planes * plane;
    if (rest > 0) {
      kernels::randn_ar1(stream, seeds_.view(Shape{rest}, tilt_planes * plane),
                         float(options_.high_order_rho), seed_, id);
    }
  }
  kernels::mul(stream, spectrum_, seeds_, planes_);
  plan_->inverse(stream, planes_, planes_);
  kernels::MixPlanesParams p;
  p.batch = batch_;
  p.out_h = grid_h_;
  p.out_w = grid_w_;
  p.scale = scale_;
  p.first2_scale = {tilt_x_, tilt_y_};
  kernels::mix_planes(stream, planes_, mix_, coefficients_, p, &tilt_);
}

}  // namespace vkjr2::sim
