#include <vkjr2/runtime/error.hpp>
#include <vkjr2/sim/p2s_blur_model.hpp>
#include <vkjr2/sim/validate.hpp>

#include <gtest/gtest.h>

#include "support/test_device.hpp"

namespace vkjr2::sim {
namespace {

// The small version of `vkjr2 sim-validate` (its --quick sizes): every
// check passes its bound (4σ, or the stated tolerance of the PSF comparison),
// the PSF checks also at the red and blue channels' wavelengths with their
// own blur models (610 nm: both separations are alias-free, 465 nm: one).
TEST(SimValidate, QuickChecksPass) {
  Device& dev = test::device();
  ValidationConfig c;
  c.fields = 100;
  c.screens = 16;
  c.psf_frames = 16;
  c.extra_wavelengths_m = {kRgbWavelengthsM[0], kRgbWavelengthsM[2]};
  const auto rows = validate_simulator(dev, "moderate", c, load_shipped_blur_models(dev));
  ASSERT_EQ(rows.size(), 21u + 11u + 7u);
  int at_610 = 0, at_465 = 0;
  for (const auto& r : rows) {
    at_610 += r.check.ends_with(" at 610 nm") ? 1 : 0;
    at_465 += r.check.ends_with(" at 465 nm") ? 1 : 0;
  }
  EXPECT_EQ(at_610, 11);
  EXPECT_EQ(at_465, 7);
  for (const auto& r : rows) {
    EXPECT_TRUE(r.pass()) << r.check << ": " << r.measured << " ± " << r.sigma << " vs "
                          << r.expected << " (tol " << r.tolerance << ")";
    EXPECT_GT(r.tolerance, 0) << r.check;
  }
  EXPECT_THROW(validate_simulator(dev, "moderate", ValidationConfig{.fields = 1}, nullptr),
               InvalidArgument);
  // A wavelength no model samples at.
  ValidationConfig far = c;
  far.extra_wavelengths_m = {800e-9};
  EXPECT_THROW(validate_simulator(dev, "moderate", far, load_default_blur_model(dev)),
               InvalidArgument);
}

}  // namespace
}  // namespace vkjr2::sim
