// Tilt in the units of a simulation: the angle and image shift of a Noll tilt
// coefficient, and the tilt variances, for a channel of the parameters
// (sim/noll.hpp has the parameter-free statistics they build on).
#pragma once

#include <vkjr2/sim/params.hpp>

namespace vkjr2::sim {

// tilt_angle_rad (sim/noll.hpp) at the channel's wavelength and aperture.
double tilt_angle_rad(double a_tilt, const Params& params, int channel = 0);
// The image shift it causes, in pixels: angle · f / pixel pitch.
double tilt_px(double a_tilt, const Params& params, int channel = 0);
// One-axis Z-tilt angle variance (2/π)² (λ/D)² ⟨a2²⟩ (D/r0)^(5/3)
// ≈ 0.182 (λ/D)² (D/r0)^(5/3) rad², for the parameters' channel.
double tilt_angle_variance_rad2(const Params& params, int channel = 0);
// One-axis G-tilt angle variance g_tilt_constant() (λ/D)² (D/r0)^(5/3) rad²
// (the PSF centroid's wander, what a camera sees).
double g_tilt_angle_variance_rad2(const Params& params, int channel = 0);

}  // namespace vkjr2::sim
