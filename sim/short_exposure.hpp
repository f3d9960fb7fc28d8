// The mean atmospheric OTF of a circular pupil in Kolmogorov turbulence
// with the tilt removed from every realization (short exposure), computed
// exactly for Gaussian phase statistics instead of by Fried's closed form
// exp{−3.44 (r/r0)^(5/3) [1 − (r/D)^(1/3)]}, which assumes the tilt and the
// rest of the phase independent (docs/sim.md §10).
//
// For a tilt-removed phase φ' = φ − T, the OTF at pupil separation r is
// (1/A(r)) ∫_{overlap} E[exp(i(φ'(x + r) − φ'(x)))] dx and, φ' being Gaussian,
// E[exp(iΔφ')] = exp(−½ D'(x, r)) with the position-dependent
//   D'(x, r) = D(r) − 2 E[Δφ ΔT] + E[ΔT²],  D(s) = 6.88 (s/r0)^(5/3),
// and E[φ(x) t] for the tilt t a linear functional of φ follows from the
// structure function (the constant part of the covariance integrates out).
// The result is divided by the diffraction OTF, i.e. it is the mean of
// exp(−½ D') over the overlap: 1 at r = 0, exp(−½ D(r)) without removal.
#pragma once

#include <cstdint>

namespace vkjr2::sim {

enum class TiltRemoval : std::uint8_t {
  none,      // long exposure
  zernike,   // the least-squares tilt a_2 Z_2 + a_3 Z_3 (the fast simulator's warp)
  centroid,  // the mean phase gradient over the pupil (G-tilt: the PSF centroid)
};

// r_over_d = r / D in (0, 1), d_over_r0 > 0, the separation along x; grid:
// pupil samples per diameter for the area integrals (the error falls as
// 1/grid²; 96 gives ~1e-4). Throws InvalidArgument outside these ranges.
double atmospheric_otf(double r_over_d, double d_over_r0, TiltRemoval removal, int grid = 96);

// The per-axis variance of the removed tilt's phase gradient over the unit
// pupil, for D/r0 = 1, in rad² per (D/2)²: 4 ⟨a_2²⟩ for zernike, ⟨g_x²⟩ for
// centroid (their ratio is c_G / c_Z = 0.933). The integrals the OTF uses.
double removed_tilt_variance(TiltRemoval removal, int grid = 96);

}  // namespace vkjr2::sim
