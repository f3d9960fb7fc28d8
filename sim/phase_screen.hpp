// FFT phase screens with von Kármán statistics and subharmonic low-frequency
// compensation (Lane, Glindemann & Dainty 1992; Johansson & Gavel 1994;
// Schmidt, "Numerical Simulation of Optical Wave Propagation", 2010, ch. 9).
// The derivation and the tests' numbers are in docs/sim.md ("Phase screens").
//
// A screen is a real M×M array of phase (radians) on a grid of spacing dx,
// sample (row r, column c) at x = (c − M/2)·dx, y = (r − M/2)·dx, row-major.
#pragma once

#include <vkjr2/runtime/device.hpp>
#include <vkjr2/sim/host_fft.hpp>

#include <complex>
#include <cstdint>
#include <limits>
#include <span>
#include <vector>

namespace vkjr2::sim {

// The sampling shared by a set of screens.
struct ScreenGrid {
  int size = 256;          // M: an FFT-supported length (kernels::fft_supported_length)
  double spacing_m = 0.0;  // dx
  // Subharmonic levels p = 1..levels (3×3 grids of spacing Δf/3^p, centre
  // excluded) restore the power below the FFT's lowest frequency
  // Δf = 1/(M dx); 0 = none. 3 is the usual choice (Schmidt 2010); the
  // Kolmogorov spectrum converges slowly below Δf (the missing share of D
  // falls as 3^(−levels/3)): 10 levels leave D(r) 2 % low at r = M dx/8 and
  // 5 % at 0.4 M dx, 3 levels 9 % and 28 % (docs/sim.md).
  int subharmonic_levels = 10;
};

// The turbulence of one screen. inner_scale_m = 0 and outer_scale_m = ∞ give
// pure Kolmogorov statistics.
struct ScreenLayer {
  double r0_m = 0.1;  // Fried parameter of this screen alone
  double inner_scale_m = 0.0;
  double outer_scale_m = std::numeric_limits<double>::infinity();
};

// Von Kármán phase PSD, f in cycles per metre (rad² m²):
//   Φ(f) = c_Φ r0^(−5/3) exp(−(f/fm)²) / (f² + f0²)^(11/6),
//   fm = 5.92 / (2π l0), f0 = 1 / L0, c_Φ = phase_psd_constant().
double von_karman_psd(double f_per_m, const ScreenLayer& layer);

// The variance a screen gives each of its frequency points: lattice bin
// (su, sv) (signed indices, spacing df = 1/(M dx)) and subharmonic point
// (kx, ky) ∈ {−1, 0, 1}² of a level of spacing dp. Φ(f) df² far from the
// origin; ∫_cell Φ(f) |f|² d²f / |f|² over the point's cell for the bins with
// |su|, |sv| ≤ 2 and every subharmonic point (docs/sim.md, "Phase screens").
double screen_lattice_variance(int su, int sv, double df, const ScreenLayer& layer);
double screen_subharmonic_variance(int kx, int ky, double dp, const ScreenLayer& layer);

// One screen per entry of `layers`, [layers.size(), M, M] row-major, radians.
// Screens are made in pairs: screens 2j and 2j+1 are the real and imaginary
// parts of one inverse c2c FFT (kernels::FftPlan, batched over the pairs) of
// a + i b, a and b independent Hermitian Gaussian spectra with
// ⟨|a(f)|²⟩ = Φ(f) Δf², cell-weighted near the origin (so each part is real and the two layers of a
// pair may have different PSDs); the subharmonics are added on the host. Deterministic: the same
// seed, grid and layers give the same screens (one sim::Rng(seed) draws every Gaussian, in a fixed
// order). Throws InvalidArgument for a bad size, spacing, r0 or scale. fft picks where the inverse
// FFT runs (FftBackend::fftw: on the CPU, device unused); the backends agree to float rounding.
std::vector<float> phase_screens(const Device& device, const ScreenGrid& grid,
                                 std::span<const ScreenLayer> layers, std::uint64_t seed,
                                 FftBackend fft = FftBackend::device);

// The expected structure function ⟨(φ(x + r e_x) − φ(x))²⟩ of the screens
// phase_screens() makes (along a grid axis, r in metres): the discrete model
// Σ 2 var(f) (1 − cos 2π f_x r) over the FFT lattice (DC excluded) and the
// subharmonic points, var(f) = Φ(f) Δf² or, for the points near the origin,
// ∫_cell Φ(f) |f|² d²f / |f|² (cell-weighted). Below Kolmogorov's
// C_D (r/r0)^(5/3) by what lies below the last subharmonic level: 2 % at
// r = M dx/8 with 10 levels (docs/sim.md); tests compare screens and wave
// optics against it.
double screen_structure_function(const ScreenGrid& grid, const ScreenLayer& layer, double r_m);

// One subharmonic term of a screen: Re(coefficient · (e^{2πi (fx x + fy y)} − 1)),
// x, y in metres from the screen's centre sample (M/2, M/2): its piston
// removed, so that deep levels (huge coefficients at tiny f) add their
// tilt and curvature without a constant that would swamp float phases. Smooth and
// defined everywhere, unlike the FFT part, which is periodic with period M dx.
struct Subharmonic {
  double fx_per_m = 0, fy_per_m = 0;
  std::complex<double> coefficient;
};

// The screens in two parts: the periodic FFT part [count, M, M] and each
// screen's subharmonic terms (4 conjugate pairs per level). phase_screens()
// is the FFT part plus the terms evaluated on the grid (same seed, same
// numbers). Wave optics reads shifted screens, so it needs them apart.
struct ScreenParts {
  std::vector<float> periodic;
  std::vector<std::vector<Subharmonic>> subharmonics;
};
ScreenParts phase_screen_parts(const Device& device, const ScreenGrid& grid,
                               std::span<const ScreenLayer> layers, std::uint64_t seed,
                               FftBackend fft = FftBackend::device);

// Convenience: `count` screens of one layer.
std::vector<float> phase_screens(const Device& device, const ScreenGrid& grid,
                                 const ScreenLayer& layer, int count, std::uint64_t seed);

}  // namespace vkjr2::sim
