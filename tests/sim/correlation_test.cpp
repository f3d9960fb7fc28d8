#include <vkjr2/runtime/error.hpp>
#include <vkjr2/sim/correlation.hpp>
#include <vkjr2/sim/noll.hpp>
#include <vkjr2/sim/params.hpp>
#include <vkjr2/sim/zernike.hpp>

#include <gtest/gtest.h>

#include <cmath>
#include <numbers>

namespace vkjr2::sim {
namespace {

constexpr double kPi = std::numbers::pi;

// The table (cubic in log s, asymptote beyond s = 20) against direct
// quadrature, relative to G_{n,0}(0).
TEST(Correlation, TableMatchesDirectQuadrature) {
  for (int n = 1; n <= 5; ++n) {
    const double g0 = layer_integral_direct(n, 0, 0.0);
    for (int nu = 0; nu <= 2 * n; nu += 2) {
      if (nu != 0 && (nu / 2) % 2 != n % 2) continue;
      for (double s : {0.0, 4e-4, 0.013, 0.21, 0.77, 1.9, 6.3, 17.0, 26.0, 45.0}) {
        SCOPED_TRACE("n=" + std::to_string(n) + " nu=" + std::to_string(nu) +
                     " s=" + std::to_string(s));
        EXPECT_NEAR(layer_integral(n, nu, s), layer_integral_direct(n, nu, s), 2e-4 * g0);
      }
    }
  }
}

TEST(Correlation, LayerCorrelationShape) {
  for (int j = 2; j <= 36; ++j) {
    EXPECT_NEAR(layer_correlation(j, 0.0, 0.3), 1.0, 1e-12) << j;
    // Correlation falls from 1 with separation (high orders then oscillate
    // about 0, so monotonic only for the tilts).
    EXPECT_LT(layer_correlation(j, 0.05, 0.0), 1.0) << j;
    for (double s = 0.25; s <= 3; s += 0.25)
      EXPECT_LE(std::fabs(layer_correlation(j, s, 0.0)), 1.0) << j;
  }
  for (int j : {2, 3}) {
    double prev = 1;
    for (double s = 0.25; s <= 3; s += 0.25) {
      const double c = layer_correlation(j, s, 0.3);
      EXPECT_LT(c, prev) << "j=" << j << " s=" << s;
      prev = c;
    }
  }
  // x-tilt decorrelates faster along x (longitudinal) than along y; Z3 is Z2 rotated.
  EXPECT_LT(layer_correlation(2, 0.5, 0.0), layer_correlation(2, 0.5, kPi / 2) - 0.05);
  EXPECT_NEAR(layer_correlation(2, 0.5, 0.0), layer_correlation(3, 0.5, kPi / 2), 1e-12);
  // m = 0 modes are isotropic.
  EXPECT_NEAR(layer_correlation(4, 0.7, 0.0), layer_correlation(4, 0.7, 1.1), 1e-12);
  EXPECT_THROW(layer_correlation(1, 0.1, 0.0), InvalidArgument);
  EXPECT_THROW(layer_integral(1, 2, -1.0), InvalidArgument);
  EXPECT_THROW(layer_integral(0, 0, 1.0), InvalidArgument);
}

// Independent check of the whole formula (normalization, anisotropy sign):
// ⟨a_j(0) a_j(Δ)⟩ = −½ ⟨Z_j(x) Z_j(x′) D_φ(|x − x′ − Δ|)⟩ over x, x′ uniform in
// the unit disk (∫ W Z_j = 0 removes the constant of the covariance). The
// one-point terms D_φ(|x − Δ|), D_φ(|x′ + Δ|) and D_φ(|Δ|) have zero mean
// against Z_j(x) Z_j(x′) and are subtracted as control variates. Divided by
// the zero-lag value (Noll's ⟨a_j²⟩) it is the one-layer correlation; the
// bound is 4σ of the Monte Carlo mean (σ from the samples).
TEST(Correlation, MatchesStructureFunctionMonteCarlo) {
  Rng rng(777);
  const double c_d = structure_function_constant();
  auto dphi = [&](double x, double y) {
    return c_d * std::pow(std::hypot(x, y) / 2, 5.0 / 3.0);
  };  // r0 = D = 2
  struct Case {
    int j;
    double s, alpha;
  };
  for (const Case& c :
       {Case{2, 0.5, 0.0}, Case{2, 0.5, kPi / 2}, Case{4, 0.4, 0.0}, Case{8, 0.3, kPi / 4}}) {
    SCOPED_TRACE("j=" + std::to_string(c.j) + " s=" + std::to_string(c.s));
    const double dx = 2 * c.s * std::cos(c.alpha), dy = 2 * c.s * std::sin(c.alpha);  // radii
    constexpr int kPairs = 1'000'000;
    double sum = 0, sum2 = 0;
    auto point = [&](double& x, double& y) {
      do {
        x = 2 * rng.uniform() - 1;
        y = 2 * rng.uniform() - 1;
      } while (x * x + y * y > 1);
    };
    const double d0 = dphi(dx, dy);
    for (int i = 0; i < kPairs; ++i) {
      double x1, y1, x2, y2;
      point(x1, y1);
      point(x2, y2);
      const double f =
          dphi(x1 - x2 - dx, y1 - y2 - dy) - dphi(x1 - dx, y1 - dy) - dphi(-x2 - dx, -y2 - dy) + d0;
      const double v = -0.5 * zernike_xy(c.j, x1, y1) * zernike_xy(c.j, x2, y2) * f;
      sum += v;
      sum2 += v * v;
    }
    const double mean = sum / kPairs;
    const double sigma = std::sqrt((sum2 / kPairs - mean * mean) / kPairs);
    const double variance = noll_covariance(c.j, c.j);
    EXPECT_NEAR(mean / variance, layer_correlation(c.j, c.s, c.alpha), 4 * sigma / variance)
        << "MC " << mean / variance << " ± " << sigma / variance;
  }
}

TEST(Correlation, PathIntegratedField) {
  Params p = preset("moderate");
  const double ifov = p.optics.pixel_pitch_m / p.optics.focal_length_m;
  FieldCorrelation corr(p, 36, 400 * ifov);
  for (int j = 2; j <= 36; ++j) EXPECT_NEAR(corr(j, 0, 0), 1.0, 1e-9) << j;
  // Tilts stay correlated over many pixels (turbulence near the camera
  // moves the whole frame); high orders decorrelate much faster.
  EXPECT_GT(corr(2, 0, 50 * ifov), 0.5);
  EXPECT_LT(corr(22, 50 * ifov, 0), corr(2, 50 * ifov, 0));
  EXPECT_NEAR(corr(2, 30 * ifov, 0), corr(3, 0, 30 * ifov), 1e-12);
  // Against a direct path integral at one point (the table is linear in θ).
  {
    const double theta = 37.3 * ifov;
    const double L = p.path.range_m, D = p.optics.aperture_m;
    double num = 0, den = 0;
    constexpr int kSteps = 4000;  // midpoint rule; Cn² constant here
    for (int i = 0; i < kSteps; ++i) {
      const double z = (i + 0.5) * L / kSteps, w = std::pow(z / L, 5.0 / 3.0);
      num += w * layer_correlation(4, theta * (L - z) / (D * z / L), 0.0);
      den += w;
    }
    EXPECT_NEAR(corr(4, theta, 0), num / den, 2e-3);
  }
  // Turbulence near the scene decorrelates the field faster than near the camera.
  Params near_scene = p, near_camera = p;
  near_scene.path.strength = near_camera.path.strength = Strength::cn2_profile;
  near_scene.path.cn2_z_m = near_camera.path.cn2_z_m = {0, 200, 300, 1000};
  near_scene.path.cn2_profile = {1e-14, 1e-14, 0, 0};
  near_camera.path.cn2_profile = {0, 0, 1e-14, 1e-14};
  FieldCorrelation cs(near_scene, 11, 100 * ifov), cc(near_camera, 11, 100 * ifov);
  EXPECT_LT(cs(2, 20 * ifov, 0), cc(2, 20 * ifov, 0));
  EXPECT_LT(cs(11, 5 * ifov, 0), cc(11, 5 * ifov, 0));
  EXPECT_THROW(corr(2, 500 * ifov, 0), InvalidArgument);
  EXPECT_THROW(corr(37, 0, 0), InvalidArgument);
  EXPECT_THROW(FieldCorrelation(p, 36, 0.0), InvalidArgument);
}

}  // namespace
}  // namespace vkjr2::sim
