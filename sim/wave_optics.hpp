// Wave-optics reference: point sources in the scene propagated by split-step
// angular-spectrum propagation through phase screens to the aperture, and
// their PSFs at the detector (Schmidt, "Numerical Simulation of Optical Wave
// Propagation", SPIE 2010, ch. 8–9; Hardie et al., Opt. Eng. 56(7) 071502,
// 2017, for shared screens across the field). The method, its sampling and
// its checks are in docs/sim.md ("Wave optics").
//
// Geometry. A point source at z = 0 gives a spherical wave. By the paraxial
// lens (Talanov) transformation U(x, z) = (L/z) u(x L/z, ζ) exp(i k x²/(2z)),
// ζ = L (1 − L/z), it is exactly a unit plane wave u in expanding coordinates
// ξ = x L/z: the screen at z_i becomes a screen ψ_i(ξ) = φ_i(ξ z_i/L) (its
// r0, l0 and L0 scaled by L/z_i) at ζ_i, planes are Δζ = L²(1/z_i − 1/z_{i+1})
// apart, and at the aperture (z = L: ζ = 0, ξ = x) u is the aperture field
// with the vacuum spherical curvature removed. That is Schmidt's
// scaled-coordinate spherical-wave propagation taken to its limit
// (source spacing → 0), with no source model to band-limit: the grid spacing
// is the same in every plane.
#pragma once

#include <vkjr2/runtime/device.hpp>
#include <vkjr2/sim/host_fft.hpp>
#include <vkjr2/sim/params.hpp>

#include <array>
#include <cstdint>
#include <limits>
#include <span>
#include <string>
#include <vector>

namespace vkjr2::sim {

struct WaveConfig {
  int grid = 256;  // N: propagation grid (an FFT length)
  // M ≥ N: side of the periodic screens (an FFT length; 0 = N). The N grid
  // reads the middle of each screen; sources at field angle θ read it shifted
  // by θ L (L − z)/z, which stays free of wrap-around while it is below
  // (M − N) δ/2 + (N δ − D)/2.
  int screen_size = 0;
  int screens = 10;  // at least this many; more when a slab's Rytov number exceeds max_rytov
  double inner_scale_m = 0.0;                                      // l0 (0: none)
  double outer_scale_m = std::numeric_limits<double>::infinity();  // L0 (∞: none)
  int subharmonic_levels = 10;      // per screen (ScreenGrid::subharmonic_levels)
  double grid_over_aperture = 2.5;  // N·δ ≈ this × D before δ is set by the detector pitch
  double max_rytov = 0.1;           // per slab (Schmidt 2010, §9.5)
  // Schmidt's super-Gaussian absorber exp(−(r/w)^16), w = 0.47 N δ, at each
  // screen. Off by default: in the ξ frame the wave is an infinite plane wave
  // and periodic screens make the periodic grid exact, while the absorber
  // removes the light that turbulence near the scene scatters sideways
  // (λΔζ/r0' ≈ the guard band) without the light that would replace it,
  // biasing the coherence high (docs/sim.md, "Wave optics").
  bool absorber = false;
  std::uint64_t seed = 1;
  // Frozen flow: every screen displaced by (x, y) metres in its own plane
  // (a transverse wind × the time since the screens were drawn); frames of a
  // video keep the seed and step this. {0, 0}: the screens as drawn.
  std::array<double, 2> screen_offset_m = {0.0, 0.0};
  // Where the FFTs (screens, split steps, pupil → PSF) run. FftBackend::fftw
  // runs the whole reference on the CPU (FFTW, one thread; the screen and
  // propagator products on the host too) and never touches the Device; the
  // two agree to float rounding (same seed: fields within 7e-6, PSFs within
  // 5e-7 of the peak at grid 64, tests/sim/wave_optics_test.cpp).
  FftBackend fft = FftBackend::device;
};

// The sampling and screens derive from Params and WaveConfig.
struct WavePlan {
  double wavelength_m = 0;
  double spacing_m = 0;  // δ: at the aperture, and in every plane of the ξ frame
  int grid = 0;          // N
  int screen_size = 0;   // M
  // Nf: the pupil field is folded into Nf×Nf and transformed, so the focal
  // sample λ f/(Nf δ) equals the pixel pitch p: δ = λ f/(p Nf).
  int pupil_fft = 0;
  std::vector<double> z_m;          // screen positions (slab centres), 0 = scene
  std::vector<double> r0_m;         // each screen's own r0 at z (physical coordinates)
  std::vector<double> r0_scaled_m;  // the same in the ξ frame: r0 L / z
  std::vector<double> rytov;        // each slab's share of σ_χ²
  // Δζ after each screen: to the next one, from the last to the aperture.
  std::vector<double> propagation_m;
  double r0_spherical_m = 0;  // from the screens: (Σ r0_scaled^(−5/3))^(−3/5); = derive()'s r0
  std::vector<std::string> warnings;
};

// Throws InvalidArgument for a bad config (grid not an FFT length, screens < 1, …).
// wave_psfs and wave_aperture_fields derive the same plan; check its
// warnings (coarse δ for r0, Rytov limit not met, plane-wave Params) here.
WavePlan plan_wave(const Params& params, int channel, const WaveConfig& config);

// The aperture fields (vacuum curvature removed) for point sources at field
// angles (θx, θy) in radians, through ONE shared set of screens:
// [sources, N, N] complex, (re, im) interleaved, sample (r, c) at
// x = (c − N/2) δ, y = (r − N/2) δ. |u| = 1 in vacuum. A source at θ sees
// screen i shifted by θ L (L − z_i)/z_i in the ξ frame (shear invariance of
// the paraxial equation); screens are periodic with period N δ.
std::vector<float> wave_aperture_fields(const Device& device, const Params& params, int channel,
                                        const WaveConfig& config,
                                        std::span<const std::array<double, 2>> angles_rad);

// PSFs (psf_size², row-major, each summing to 1, centred at (psf_size/2,
// psf_size/2), the geometric image position removed) of point sources at the
// given field angles through one shared set of screens: the aperture field ×
// the pupil (diameter D) → |FFT_Nf|², point samples at the pixel pitch.
// psf_size ≤ Nf (the PSF's period in pixels).
std::vector<float> wave_psfs(const Device& device, const Params& params, int channel,
                             const WaveConfig& config,
                             std::span<const std::array<double, 2>> angles_rad, int psf_size);

}  // namespace vkjr2::sim
