#include <vkjr2/sim/noll.hpp>
#include <vkjr2/sim/tilt.hpp>

#include <cmath>
#include <numbers>

namespace vkjr2::sim {
namespace {
constexpr double kPi = std::numbers::pi;
}  // namespace

double tilt_angle_rad(double a_tilt, const Params& params, int channel) {
  return tilt_angle_rad(a_tilt, channel_wavelength_m(params, channel), params.optics.aperture_m);
}

double tilt_px(double a_tilt, const Params& params, int channel) {
  return tilt_angle_rad(a_tilt, params, channel) * params.optics.focal_length_m /
         pixel_pitch_m(params);
}

double tilt_angle_variance_rad2(const Params& params, int channel) {
  const Derived d = derive(params);
  const ChannelDerived& c = d.channels.at(static_cast<std::size_t>(channel));
  const double lam_d = c.wavelength_m / params.optics.aperture_m;
  return std::pow(2 / kPi, 2) * lam_d * lam_d * noll_covariance(2, 2) *
         std::pow(c.d_over_r0, 5.0 / 3.0);
}

double g_tilt_angle_variance_rad2(const Params& params, int channel) {
  const Derived d = derive(params);
  const ChannelDerived& c = d.channels.at(static_cast<std::size_t>(channel));
  const double lam_d = c.wavelength_m / params.optics.aperture_m;
  return g_tilt_constant() * lam_d * lam_d * std::pow(c.d_over_r0, 5.0 / 3.0);
}

}  // namespace vkjr2::sim
