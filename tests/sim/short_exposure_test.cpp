#include <vkjr2/runtime/error.hpp>
#include <vkjr2/sim/noll.hpp>
#include <vkjr2/sim/short_exposure.hpp>

#include <gtest/gtest.h>

#include <cmath>
#include <numbers>

namespace vkjr2::sim {
namespace {

constexpr double kPi = std::numbers::pi;

double fried(double u, double d_over_r0, double alpha) {
  return std::exp(-3.44 * std::pow(u * d_over_r0, 5.0 / 3.0) * (1 - alpha * std::cbrt(u)));
}

// The tilt functionals against the closed forms: 4⟨a_2²⟩ = 4 · Noll's
// covariance (the disk raster's edge: ~1 % at 64 samples) and the mean
// gradient's ⟨g_x²⟩ = π² c_G (a contour integral: 1e-4).
TEST(ShortExposure, TiltVariancesMatchNollAndTheGTiltConstant) {
  const double z = removed_tilt_variance(TiltRemoval::zernike, 64);
  const double g = removed_tilt_variance(TiltRemoval::centroid, 64);
  const double noll = 4 * noll_covariance(2, 2);
  EXPECT_NEAR(z / noll, 1.0, 0.02);
  // Angle variances: (λ/(πD))² times the gradient variances, so c_G = ⟨g_x²⟩/π²
  // (g_tilt_constant's own 1-D integral) and c_Z = 4⟨a_2²⟩/π².
  EXPECT_NEAR(g / (kPi * kPi), g_tilt_constant(), 2e-4);
  EXPECT_NEAR(g / z, 0.933, 0.02);
  EXPECT_EQ(removed_tilt_variance(TiltRemoval::none), 0.0);
}

// No removal is the long exposure exactly; with the tilt removed the exact
// OTF is above it, near Fried's alpha = 1 form at small r (within 0.003 at
// r ≤ 0.1 D) and above it at 0.2 D (Fried's independence assumption), and
// it converges in the grid.
TEST(ShortExposure, ExactOtfAgainstFriedsForms) {
  for (double k : {1.0, 3.0, 5.0}) {
    for (double u : {0.05, 0.1, 0.2}) {
      const double none = atmospheric_otf(u, k, TiltRemoval::none, 32);
      EXPECT_DOUBLE_EQ(none, fried(u, k, 0)) << u << " " << k;
      const double z = atmospheric_otf(u, k, TiltRemoval::zernike, 48);
      const double c = atmospheric_otf(u, k, TiltRemoval::centroid, 48);
      EXPECT_GT(z, none) << u << " " << k;
      EXPECT_GT(c, none) << u << " " << k;
      if (u <= 0.1) {
        EXPECT_NEAR(z, fried(u, k, 1), 0.003) << u << " " << k;
        EXPECT_NEAR(c, fried(u, k, 1), 0.003) << u << " " << k;
      } else {
        EXPECT_GT(z, fried(u, k, 1) - 1e-3) << u << " " << k;
      }
    }
  }
  const double coarse = atmospheric_otf(0.1, 3.0, TiltRemoval::zernike, 32);
  const double fine = atmospheric_otf(0.1, 3.0, TiltRemoval::zernike, 64);
  EXPECT_NEAR(coarse, fine, 1e-3);
  EXPECT_THROW(atmospheric_otf(0.0, 3.0, TiltRemoval::zernike), InvalidArgument);
  EXPECT_THROW(atmospheric_otf(0.1, std::nan(""), TiltRemoval::zernike), InvalidArgument);
  EXPECT_THROW(atmospheric_otf(0.1, 3.0, TiltRemoval::zernike, 4), InvalidArgument);
}

}  // namespace
}  // namespace vkjr2::sim
