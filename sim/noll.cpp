#include <vkjr2/runtime/error.hpp>
#include <vkjr2/sim/noll.hpp>
#include <vkjr2/sim/quadrature.hpp>
#include <vkjr2/sim/zernike.hpp>

#include <cmath>
#include <cstdio>
#include <numbers>
#include <string>

namespace vkjr2::sim {
namespace {

constexpr double kPi = std::numbers::pi;

double beta(double a, double b) { return std::tgamma(a) * std::tgamma(b) / std::tgamma(a + b); }

void check_mode(int j, const char* op) {
  if (j < 2)
    throw InvalidArgument(
        op, "Noll index " + std::to_string(j) + " is below 2",
        "piston (j = 1) is excluded: its Kolmogorov variance is infinite; start at j = 2");
}

int checked_sampler_modes(int j_max) {
  if (j_max < 3 || j_max > kMaxZernikeModes + 1)
    throw InvalidArgument(
        "sim::NollSampler", "j_max = " + std::to_string(j_max) + " is out of range",
        "use 3 ≤ j_max ≤ " + std::to_string(kMaxZernikeModes + 1) + " (36 by default)");
  return j_max;
}

}  // namespace

double structure_function_constant() {
  // Fried 1965: D_φ(r) = 2 [(24/5) Γ(6/5)]^(5/6) (r/r0)^(5/3).
  return 2 * std::pow(24.0 / 5.0 * std::tgamma(6.0 / 5.0), 5.0 / 6.0);
}

double phase_psd_constant() {
  // The PSD c r0^(−5/3) f^(−11/3) whose structure function
  // 2∫(1 − cos 2πf·r) Φ(f) d²f equals C_D (r/r0)^(5/3) (docs/sim.md, eq. P1).
  return std::pow(std::tgamma(11.0 / 6.0), 2) / (2 * std::pow(kPi, 11.0 / 3.0)) *
         std::pow(24.0 / 5.0 * std::tgamma(6.0 / 5.0), 5.0 / 6.0);
}

double noll_constant() {
  // docs/sim.md eq. N3: K = c_Φ Γ(14/3) π^(8/3) 2^(−5/3).
  return phase_psd_constant() * std::tgamma(14.0 / 3.0) * std::pow(kPi, 8.0 / 3.0) *
         std::pow(2.0, -5.0 / 3.0);
}

double noll_covariance(int i, int j) {
  check_mode(i, "sim::noll_covariance");
  check_mode(j, "sim::noll_covariance");
  const ZernikeIndex a = noll_index(i);
  const ZernikeIndex b = noll_index(j);
  // Same azimuthal order; for m ≠ 0 also the same parity (cos with cos, sin
  // with sin). m = 0 pairs (e.g. Z4–Z11) are correlated regardless of parity.
  if (a.m != b.m) return 0.0;
  if (a.m != 0 && a.sine != b.sine) return 0.0;
  const double n = a.n;
  const double np = b.n;
  const int sign_exp = (a.n + b.n - 2 * a.m) / 2;
  const double sign = sign_exp % 2 == 0 ? 1.0 : -1.0;
  // Noll 1976 eq. 25 (Weber–Schafheitlin integral of J_{n+1} J_{n'+1} k^(−14/3)).
  return noll_constant() * sign * std::sqrt((n + 1) * (np + 1)) *
         std::tgamma((n + np - 5.0 / 3.0) / 2) /
         (std::tgamma((np - n + 17.0 / 3.0) / 2) * std::tgamma((n - np + 17.0 / 3.0) / 2) *
          std::tgamma((n + np + 23.0 / 3.0) / 2));
}

std::vector<double> noll_covariance_matrix(int j_max) {
  if (j_max < 2 || j_max > 5151)
    throw InvalidArgument("sim::noll_covariance_matrix",
                          "j_max = " + std::to_string(j_max) + " is out of range",
                          "use j_max ≥ 2 (36 by default)");
  const int n = j_max - 1;
  std::vector<double> c(static_cast<std::size_t>(n) * n);
  for (int r = 0; r < n; ++r)
    for (int k = 0; k < n; ++k)
      c[static_cast<std::size_t>(r) * n + k] = noll_covariance(r + 2, k + 2);
  return c;
}

double piston_removed_variance() {
  // ⟨r^p⟩ for two uniform points in a unit-diameter disk, from the distance
  // density (16 r/π)(arccos r − r√(1 − r²)) (docs/sim.md eq. N5):
  // (8/π) [B((p+3)/2, 1/2)/(p+2) − B((p+3)/2, 3/2)].
  const double p = 5.0 / 3.0;
  const double moment = 8 / kPi * (beta((p + 3) / 2, 0.5) / (p + 2) - beta((p + 3) / 2, 1.5));
  return 0.5 * structure_function_constant() * moment;
}

double noll_residual(int last_j) {
  if (last_j < 1)
    throw InvalidArgument("sim::noll_residual", "J = " + std::to_string(last_j) + " is below 1",
                          "Δ_J is defined for J ≥ 1 (Δ1 = piston removed)");
  double d = piston_removed_variance();
  for (int j = 2; j <= last_j; ++j) d -= noll_covariance(j, j);
  return d;
}

std::vector<double> cholesky(std::span<const double> a, int n) {
  if (n <= 0 || a.size() != static_cast<std::size_t>(n) * n)
    throw InvalidArgument(
        "sim::cholesky",
        "matrix has " + std::to_string(a.size()) + " values for n = " + std::to_string(n),
        "pass n × n values, row-major");
  std::vector<double> l(a.size(), 0.0);
  auto at = [n](std::vector<double>& m, int r, int c) -> double& {
    return m[static_cast<std::size_t>(r) * n + c];
  };
  for (int c = 0; c < n; ++c) {
    double d = a[static_cast<std::size_t>(c) * n + c];
    for (int k = 0; k < c; ++k) d -= at(l, c, k) * at(l, c, k);
    if (!(d > 0) || !std::isfinite(d))
      throw InvalidArgument("sim::cholesky",
                            "the matrix is not positive definite (pivot " + std::to_string(c) +
                                " is " + std::to_string(d) + ")",
                            "pass a symmetric positive-definite covariance");
    const double s = std::sqrt(d);
    at(l, c, c) = s;
    for (int r = c + 1; r < n; ++r) {
      double v = a[static_cast<std::size_t>(r) * n + c];
      for (int k = 0; k < c; ++k) v -= at(l, r, k) * at(l, c, k);
      at(l, r, c) = v / s;
    }
  }
  return l;
}

double Rng::uniform() { return static_cast<double>(engine_() >> 11) * 0x1.0p-53; }

double Rng::normal() {
  if (has_spare_) {
    has_spare_ = false;
    return spare_;
  }
  // Marsaglia & Bray 1964 polar method.
  double u = 0;
  double v = 0;
  double s = 0;
  do {
    u = 2 * uniform() - 1;
    v = 2 * uniform() - 1;
    s = u * u + v * v;
  } while (s >= 1 || s == 0);
  const double f = std::sqrt(-2 * std::log(s) / s);
  spare_ = v * f;
  has_spare_ = true;
  return u * f;
}

NollSampler::NollSampler(int j_max)
    : j_max_(checked_sampler_modes(j_max)),
      cov_(noll_covariance_matrix(j_max)),
      chol_(cholesky(cov_, j_max - 1)) {}

void NollSampler::sample(Rng& rng, double d_over_r0, std::span<double> out) const {
  const int n = modes();
  if (out.size() != static_cast<std::size_t>(n))
    throw InvalidArgument(
        "sim::NollSampler::sample",
        "output has " + std::to_string(out.size()) + " values for " + std::to_string(n) + " modes",
        "pass j_max − 1 values (a_2..a_jmax)");
  if (!(d_over_r0 >= 0) || !std::isfinite(d_over_r0))
    throw InvalidArgument("sim::NollSampler::sample", "D/r0 = " + std::to_string(d_over_r0),
                          "pass a finite D/r0 ≥ 0");
  const double scale = std::pow(d_over_r0, 5.0 / 6.0);
  double noise[kMaxZernikeModes];
  for (int k = 0; k < n; ++k) noise[k] = rng.normal();
  for (int r = 0; r < n; ++r) {
    const double* row = chol_.data() + static_cast<std::size_t>(r) * n;
    double acc = 0;
    for (int k = 0; k <= r; ++k) acc += row[k] * noise[k];
    out[static_cast<std::size_t>(r)] = scale * acc;
  }
}

std::vector<double> NollSampler::sample(Rng& rng, double d_over_r0, int count) const {
  if (count < 0)
    throw InvalidArgument("sim::NollSampler::sample", "count is negative", "pass count ≥ 0");
  const std::size_t n = static_cast<std::size_t>(modes());
  std::vector<double> out(n * static_cast<std::size_t>(count));
  for (int i = 0; i < count; ++i)
    sample(rng, d_over_r0, std::span<double>(out.data() + n * static_cast<std::size_t>(i), n));
  return out;
}

double tilt_angle_rad(double a_tilt, double wavelength_m, double aperture_m) {
  // φ = a·2ρcosθ = a·2x/R ⇒ ∂φ/∂x = 2a/R; angle = (λ/2π)∂φ/∂x = (2/π) a λ/D.
  return 2 / kPi * a_tilt * wavelength_m / aperture_m;
}

double g_tilt_constant() {
  // D = 1, r0 = 1: R = 1/2, A = π/4; the integrand is even about u = π, so
  // twice the integral over [0, π] (its u^(5/3) kink at 0 costs Gauss–Legendre
  // little: 256 nodes agree with a 6000² midpoint sum to 1e-5).
  static const double c = [] {
    const GaussLegendre gl(256);
    const double r = 0.5, area = kPi * r * r;
    double integral = 0;
    for (std::size_t i = 0; i < gl.x.size(); ++i) {
      const double u = kPi * (gl.x[i] + 1) / 2;
      integral += gl.w[i] * (kPi / 2) * std::cos(u) * structure_function_constant() *
                  std::pow(2 * r * std::sin(u / 2), 5.0 / 3.0);
    }
    const double gradient_variance = -(kPi * r * r / (2 * area * area)) * 2 * integral;
    return gradient_variance / (4 * kPi * kPi);  // angle = (λ/2π) · gradient
  }();
  return c;
}

}  // namespace vkjr2::sim
