#include <vkjr2/runtime/error.hpp>
#include <vkjr2/sim/blur_model.hpp>
#include <vkjr2/sim/validate.hpp>

#include <gtest/gtest.h>

#include "support/test_device.hpp"

namespace vkjr2::sim {
namespace {

// The small version of `vkjr2 sim-validate` (its --quick sizes): every
// check passes its bound (4σ, or the stated tolerance of the PSF comparison).
TEST(SimValidate, QuickChecksPass) {
  Device& dev = test::device();
  ValidationConfig c;
  c.fields = 100;
  c.screens = 16;
  c.psf_frames = 16;
  const auto rows = validate_simulator(dev, "moderate", c, load_default_blur_model(dev));
  ASSERT_EQ(rows.size(), 21u);
  for (const auto& r : rows) {
    EXPECT_TRUE(r.pass()) << r.check << ": " << r.measured << " ± " << r.sigma << " vs "
                          << r.expected << " (tol " << r.tolerance << ")";
    EXPECT_GT(r.tolerance, 0) << r.check;
  }
  EXPECT_THROW(validate_simulator(dev, "moderate", ValidationConfig{.fields = 1}, nullptr),
               InvalidArgument);
}

}  // namespace
}  // namespace vkjr2::sim
