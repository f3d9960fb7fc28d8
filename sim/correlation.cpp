#include <vkjr2/runtime/error.hpp>
#include <vkjr2/sim/correlation.hpp>
#include <vkjr2/sim/quadrature.hpp>
#include <vkjr2/sim/zernike.hpp>

#include <algorithm>
#include <array>
#include <cmath>
#include <memory>
#include <mutex>
#include <numbers>
#include <string>

namespace vkjr2::sim {
namespace {

constexpr int kMaxOrder = 20;  // n ≤ 20 ⇔ j ≤ 231 (kMaxZernikeModes)
// Table nodes: s = k / 64 up to 4 (fine enough for the oscillations of
// the high orders), then 16 per octave up to 20; beyond, the asymptote.
constexpr int kLinearPerUnit = 64;
constexpr double kLinearEnd = 4.0;
constexpr int kPerOctave = 16;
constexpr double kTableMaxS = 20.0;
constexpr int kMinTableOrder = 7;  // j ≤ 36
constexpr double kUpperU = 24.0;   // ∫ beyond u = 24 is < 1e-8 of G(0)

const GaussLegendre& gl16() {
  static const GaussLegendre g(16);
  return g;
}

void require_order(int n, int nu, const char* op) {
  if (n < 1 || n > kMaxOrder || nu < 0 || nu % 2 != 0 || nu > 2 * n) {
    throw InvalidArgument(op, "needs 1 <= n <= " + std::to_string(kMaxOrder) +
                                  " and an even nu <= 2n, got n=" + std::to_string(n) +
                                  " nu=" + std::to_string(nu));
  }
}

// J_0(x) .. J_max_order(x): upward recurrence from J_0, J_1 where it is
// stable (x ≥ max_order), the library function order by order elsewhere.
void bessel_orders(int max_order, double x, std::array<double, 2 * kMaxOrder + 2>& out) {
  if (x >= max_order && x > 0) {
    out[0] = std::cyl_bessel_j(0.0, x);
    if (max_order >= 1) out[1] = std::cyl_bessel_j(1.0, x);
    for (int k = 1; k < max_order; ++k)
      out[std::size_t(k) + 1] = 2 * k / x * out[std::size_t(k)] - out[std::size_t(k) - 1];
  } else {
    for (int k = 0; k <= max_order; ++k)
      out[std::size_t(k)] = x == 0 ? (k == 0 ? 1.0 : 0.0) : std::cyl_bessel_j(k, x);
  }
}

// G_{n,ν}(s) for all (n ≤ n_max, even ν ≤ 2n) at one s, on one node set:
// u = t³ on [0, 1] (removes the u^(−2/3) end point of n = 1), then panels
// short enough for J_ν(2su) (period π/s in u) on [1, kUpperU].
// out[n][ν/2].
std::vector<std::vector<double>> integrate_all(int n_max, double s) {
  std::vector<std::vector<double>> out(std::size_t(n_max) + 1);
  for (int n = 1; n <= n_max; ++n) out[std::size_t(n)].assign(std::size_t(n) + 1, 0.0);
  const auto& g = gl16();
  std::array<double, 2 * kMaxOrder + 2> ju{}, jnu{};
  auto accumulate = [&](double u, double weight) {
    const double base = std::pow(u, -14.0 / 3.0) * weight;
    bessel_orders(n_max + 1, u, ju);
    bessel_orders(2 * n_max, 2 * s * u, jnu);
    for (int n = 1; n <= n_max; ++n) {
      const double jn = ju[std::size_t(n) + 1];
      const double f = base * jn * jn;
      auto& row = out[std::size_t(n)];
      for (int m = n % 2; m <= n; m += 2) row[std::size_t(m)] += f * jnu[2 * std::size_t(m)];
      if (n % 2 == 1) row[0] += f * jnu[0];  // ν = 0 for odd n
    }
  };
  const int panels_a = std::max(4, static_cast<int>(std::ceil(4 * s)));
  for (int p = 0; p < panels_a; ++p) {
    const double a = double(p) / panels_a, half = 0.5 / panels_a;
    for (std::size_t i = 0; i < g.x.size(); ++i) {
      const double t = a + half * (g.x[i] + 1);
      accumulate(t * t * t, half * g.w[i] * 3 * t * t);
    }
  }
  const double h = std::min(0.5, 1.0 / std::max(s, 1e-9));
  const int panels_b = static_cast<int>(std::ceil((kUpperU - 1) / h));
  const double width = (kUpperU - 1) / panels_b;
  for (int p = 0; p < panels_b; ++p) {
    const double a = 1 + p * width, half = width / 2;
    for (std::size_t i = 0; i < g.x.size(); ++i) accumulate(a + half * (g.x[i] + 1), half * g.w[i]);
  }
  return out;
}

// Large s: only small u matters, where u^(−14/3) J_{n+1}(u)² ≈ c_n u^p with
// p = 2n + 2 − 14/3 and c_n = [2^(n+1) (n+1)!]^(−2); and
// ∫₀^∞ u^p J_ν(au) du = a^(−p−1) 2^p Γ((ν+p+1)/2) / Γ((ν−p+1)/2) (Watson §13.24,
// continued analytically in p; p is never an even integer here).
double asymptote(int n, int nu, double s) {
  const double p = 2 * n + 2 - 14.0 / 3.0;
  const double c = std::pow(2.0, -2.0 * (n + 1)) / std::pow(std::tgamma(n + 2.0), 2);
  return c * std::pow(2.0, p) * std::tgamma((nu + p + 1) / 2) / std::tgamma((nu - p + 1) / 2) *
         std::pow(2 * s, -p - 1);
}

// Fractional table index of s (s ≤ kTableMaxS) and the s of an index.
double table_index(double s) {
  return s <= kLinearEnd ? s * kLinearPerUnit
                         : kLinearEnd * kLinearPerUnit + kPerOctave * std::log2(s / kLinearEnd);
}
double table_s(int k) {
  const int linear = static_cast<int>(kLinearEnd * kLinearPerUnit);
  return k <= linear ? double(k) / kLinearPerUnit
                     : kLinearEnd * std::exp2(double(k - linear) / kPerOctave);
}

struct UniversalTable {
  int n_max = 0;
  std::vector<std::vector<std::vector<double>>> g;  // g[k][n][m] at s = table_s(k)
};

// Built on first use for the orders asked for (at least j ≤ 36), rebuilt
// larger when a higher order is asked for; never freed.
const UniversalTable& universal_table(int n) {
  static std::mutex mutex;
  static std::vector<std::unique_ptr<UniversalTable>> tables;
  const std::lock_guard<std::mutex> lock(mutex);
  for (const auto& t : tables)
    if (t->n_max >= n) return *t;
  auto t = std::make_unique<UniversalTable>();
  t->n_max = std::max(n, kMinTableOrder);
  const int count = static_cast<int>(std::ceil(table_index(kTableMaxS))) + 1;
  for (int k = 0; k < count; ++k) t->g.push_back(integrate_all(t->n_max, table_s(k)));
  tables.push_back(std::move(t));
  return *tables.back();
}

}  // namespace

double layer_integral_direct(int n, int nu, double s) {
  require_order(n, nu, "layer_integral_direct");
  if (!(s >= 0) || !std::isfinite(s))
    throw InvalidArgument("layer_integral_direct", "s must be finite and >= 0");
  if (nu != 0 && (nu / 2) % 2 != n % 2) return 0.0;  // no such (n, m) pair
  return integrate_all(n, s)[std::size_t(n)][std::size_t(nu / 2)];
}

double layer_integral(int n, int nu, double s) {
  require_order(n, nu, "layer_integral");
  if (!(s >= 0) || !std::isfinite(s))
    throw InvalidArgument("layer_integral", "s must be finite and >= 0");
  const int m = nu / 2;
  if (nu != 0 && m % 2 != n % 2) return 0.0;
  const UniversalTable& t = universal_table(n);
  const std::size_t nn = std::size_t(n), mm = std::size_t(m);
  const int last = static_cast<int>(t.g.size()) - 1;
  if (s >= table_s(last)) return asymptote(n, nu, s);
  // Catmull–Rom in the table index; G is even in s, so index −1 mirrors 1.
  const double x = table_index(s);
  const int k = std::min(static_cast<int>(x), last - 1);
  const double f = x - k;
  auto at = [&](int i) { return t.g[std::size_t(std::min(std::abs(i), last))][nn][mm]; };
  const double p0 = at(k - 1), p1 = at(k), p2 = at(k + 1), p3 = at(k + 2);
  return p1 +
         0.5 * f * (p2 - p0 + f * (2 * p0 - 5 * p1 + 4 * p2 - p3 + f * (3 * (p1 - p2) + p3 - p0)));
}

namespace {

// ε (−1)^m of the J_{2m} term: +1 for cos modes, −1 for sin modes.
double anisotropy_sign(const ZernikeIndex& z) {
  const double parity = z.m % 2 == 0 ? 1.0 : -1.0;
  return z.sine ? -parity : parity;
}

}  // namespace

double layer_correlation(int j, double s, double alpha_rad) {
  if (j < 2)
    throw InvalidArgument("layer_correlation",
                          "needs a Noll index j >= 2 (piston has no correlation)");
  const ZernikeIndex z = noll_index(j);
  const double g0 = layer_integral(z.n, 0, 0.0);
  double c = layer_integral(z.n, 0, s);
  if (z.m > 0)
    c += anisotropy_sign(z) * layer_integral(z.n, 2 * z.m, s) * std::cos(2 * z.m * alpha_rad);
  return c / g0;
}

FieldCorrelation::FieldCorrelation(const Params& params, int j_max, double max_angle_rad)
    : j_max_(j_max), max_angle_(max_angle_rad) {
  validate(params);
  if (j_max < 2 || j_max > kMaxZernikeModes) {
    throw InvalidArgument("FieldCorrelation",
                          "j_max must be in 2.." + std::to_string(kMaxZernikeModes));
  }
  if (!(max_angle_rad > 0) || !std::isfinite(max_angle_rad)) {
    throw InvalidArgument("FieldCorrelation", "max_angle_rad must be finite and > 0");
  }
  n_max_ = noll_index(j_max).n;
  constexpr int kSteps = 1024;
  step_ = max_angle_rad / kSteps;
  const double range = params.path.range_m;
  const double aperture = params.optics.aperture_m;
  const bool spherical = params.path.wave == WaveModel::spherical;
  // Path nodes: 8 panels × 16-point Gauss–Legendre over (0, L).
  struct Node {
    double weight, s_per_rad;
  };
  std::vector<Node> nodes;
  double total = 0;
  const auto& g = gl16();
  constexpr int kPanels = 8;
  for (int p = 0; p < kPanels; ++p) {
    const double half = range / kPanels / 2, a = p * range / kPanels;
    for (std::size_t i = 0; i < g.x.size(); ++i) {
      const double z = a + half * (g.x[i] + 1);
      const double u = z / range;
      const double footprint = spherical ? aperture * u : aperture;
      const double w =
          half * g.w[i] * cn2_at(params, z) * (spherical ? std::pow(u, 5.0 / 3.0) : 1.0);
      nodes.push_back({w, (range - z) / footprint});
      total += w;
    }
  }
  if (total <= 0) {
    // No turbulence: weights are moot; use the path geometry alone.
    for (auto& nd : nodes) nd.weight = 1;
    total = double(nodes.size());
  }
  tables_.resize(std::size_t(n_max_) + 1);
  for (int n = 1; n <= n_max_; ++n) {
    auto& per_n = tables_[std::size_t(n)];
    per_n.resize(std::size_t(n) + 1);
    const double g0 = layer_integral(n, 0, 0.0);
    for (int m = 0; m <= n; ++m) {
      if (m != 0 && m % 2 != n % 2) continue;
      auto& col = per_n[std::size_t(m)];
      col.resize(kSteps + 2);
      for (int k = 0; k <= kSteps + 1; ++k) {
        const double theta = k * step_;
        double acc = 0;
        for (const Node& nd : nodes)
          acc += nd.weight * layer_integral(n, 2 * m, theta * nd.s_per_rad);
        col[std::size_t(k)] = acc / (total * g0);
      }
    }
  }
}

double FieldCorrelation::table(int n, int nu, double theta) const {
  const auto& col = tables_[std::size_t(n)][std::size_t(nu / 2)];
  const double x = theta / step_;
  const auto k = std::min(static_cast<std::size_t>(x), col.size() - 2);
  const double f = x - double(k);
  return col[k] + f * (col[k + 1] - col[k]);
}

double FieldCorrelation::operator()(int j, double dx_rad, double dy_rad) const {
  if (j < 2 || j > j_max_) {
    throw InvalidArgument("FieldCorrelation", "mode j=" + std::to_string(j) + " is outside 2.." +
                                                  std::to_string(j_max_));
  }
  const double theta = std::hypot(dx_rad, dy_rad);
  if (!(theta <= max_angle_ * (1 + 1e-9))) {
    throw InvalidArgument("FieldCorrelation", "separation " + std::to_string(theta) +
                                                  " rad is beyond the tabulated " +
                                                  std::to_string(max_angle_) + " rad");
  }
  const ZernikeIndex z = noll_index(j);
  double c = table(z.n, 0, theta);
  if (z.m > 0 && theta > 0) {
    c += anisotropy_sign(z) * table(z.n, 2 * z.m, theta) *
         std::cos(2 * z.m * std::atan2(dy_rad, dx_rad));
  }
  return c;
}

}  // namespace vkjr2::sim
