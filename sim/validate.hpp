// The simulator's physics checks at a chosen size: each a statistic with its
// estimator's σ, the value theory (or the reference) expects, and a verdict
// at 4σ (or a stated tolerance where the comparison is between models).
// `vkjr2 sim-validate` runs them at full size and prints the table; the test
// suite runs them small (tests/sim/validate_test.cpp).
#pragma once

#include <vkjr2/runtime/device.hpp>
#include <vkjr2/sim/params.hpp>
#include <vkjr2/sim/simulator.hpp>

#include <functional>
#include <memory>
#include <string>
#include <vector>

namespace vkjr2::sim {

struct ValidationRow {
  std::string check;     // what is measured
  double measured = 0;   // the estimate
  double sigma = 0;      // its standard error (0 for exact comparisons)
  double expected = 0;   // theory / reference
  double tolerance = 0;  // |measured − expected| ≤ tolerance passes (4σ, or stated)
  std::string note;      // e.g. what else it is compared with
  bool pass() const;
};

// Mean of independent estimates and its standard error.
struct MeanEstimate {
  double mean = 0, sigma = 0;
};
MeanEstimate mean_and_error(const std::vector<double>& samples);

struct ValidationConfig {
  // Fields: `fields` independent 96×128 frames (tilt and Noll statistics).
  int fields = 600;
  // Phase screens: `screens` 128² screens for the structure function.
  int screens = 64;
  // Wave optics vs the fast simulator: `psf_frames` realizations of a point
  // source through each.
  int psf_frames = 96;
  // Side M of the wave reference's periodic phase screens (its propagation
  // grid is 128, δ ≈ D/52). Their tilt converges slowly in M even with subharmonics:
  // G-tilt variance 0.85, 0.93, 0.96 of c_G at M = 128, 256, 512, and the
  // short-exposure MTF at 0.1 D was 3.8σ low at M = 128 (docs/sim.md §10).
  int wave_screen_size = 512;
  std::uint64_t seed = 2026;
  // The PSF checks again at each of these wavelengths (same optics: another
  // sampling and r0), each with the blur model made for its sampling.
  std::vector<double> extra_wavelengths_m;
};

// progress(done, total) after each check. blur: the fast simulator's blur
// model (for the PSF comparison; null skips it).
std::vector<ValidationRow> validate_simulator(const Device& device, const std::string& preset_name,
                                              const ValidationConfig& config,
                                              const std::shared_ptr<const BlurModel>& blur,
                                              const std::function<void(int, int)>& progress = {});
// With several blur models: every wavelength's checks take the model that
// matches its sampling (an InvalidArgument when none does).
std::vector<ValidationRow> validate_simulator(
    const Device& device, const std::string& preset_name, const ValidationConfig& config,
    const std::vector<std::shared_ptr<const BlurModel>>& blur,
    const std::function<void(int, int)>& progress = {});

}  // namespace vkjr2::sim
