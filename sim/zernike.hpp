// Zernike polynomials with Noll's indexing and normalization (Noll 1976,
// J. Opt. Soc. Am. 66(3), 207–211, eqs. 1–3 and Table I).
//
// Z_j(ρ, θ) on the unit disk, j ≥ 1, normalized so that (1/π)∫∫ Z_j² ρ dρ dθ = 1:
//   m = 0:          Z_j = √(n+1) R_n^0(ρ)
//   m ≠ 0, j even:  Z_j = √(2(n+1)) R_n^m(ρ) cos(mθ)
//   m ≠ 0, j odd:   Z_j = √(2(n+1)) R_n^m(ρ) sin(mθ)
// Within a radial order n, j increases with m. Z2 = 2ρ cosθ is the x tilt,
// Z3 = 2ρ sinθ the y tilt, Z4 = √3 (2ρ² − 1) defocus.
//
// Pupil grids: θ is measured from the +x axis (increasing column index)
// toward +y (increasing row index), so Z2 tilts along columns and Z3 along rows.
#pragma once

#include <span>
#include <vector>

namespace vkjr2::sim {

// The highest Noll index the simulator samples and models: radial order n ≤ 20.
inline constexpr int kMaxZernikeModes = 231;

struct ZernikeIndex {
  int n = 0;          // radial order
  int m = 0;          // azimuthal order, m ≥ 0
  bool sine = false;  // sin(mθ) (odd j, m ≠ 0) rather than cos(mθ)
};

// Noll j ≥ 1 → (n, m, parity). Throws InvalidArgument for j < 1.
ZernikeIndex noll_index(int j);
// (n, m ≥ 0, parity) → Noll j. Throws InvalidArgument when (n, m) is not a
// Zernike pair (m > n, n − m odd) or when m = 0 and sine is asked for.
int noll_j(int n, int m, bool sine);
// Number of modes with radial order ≤ n: (n+1)(n+2)/2.
int noll_count_through_order(int n);

// R_n^m(ρ), 0 ≤ m ≤ n, n − m even (zero otherwise), by the recurrence
// R_n^m = ρ (R_{n−1}^{|m−1|} + R_{n−1}^{m+1}) − R_{n−2}^m, which avoids the
// cancellation of the explicit factorial sum at high order.
double zernike_radial(int n, int m, double rho);

// Z_j at polar (ρ, θ). ρ > 1 is evaluated by the same polynomial.
double zernike(int j, double rho, double theta);
// Z_j at Cartesian (x, y) in units of the pupil radius.
double zernike_xy(int j, double x, double y);

// A square sampling of the pupil for wave-optics PSFs: size × size samples,
// row-major, pupil diameter `diameter_px` samples (≤ size for zero padding),
// centred at ((size−1)/2, (size−1)/2). Sample (row r, column c) is at
// x = (c − (size−1)/2)·2/diameter_px, y = (r − (size−1)/2)·2/diameter_px in
// units of the pupil radius; it is inside the pupil when x² + y² ≤ 1. The
// sample spacing in metres is D / diameter_px.
struct PupilGrid {
  int size = 64;
  double diameter_px = 64;
};

// 1 inside the pupil, 0 outside (size² values).
std::vector<double> pupil_mask(const PupilGrid& grid);

// Modes first_j..last_j on the grid, stacked: mode (first_j + k) occupies
// values [k·size², (k+1)·size²); zero outside the pupil.
std::vector<double> zernike_modes(int first_j, int last_j, const PupilGrid& grid);

// phase = Σ_k coeffs[k] · Z_{first_j + k} inside the pupil, 0 outside
// (size² values, radians when the coefficients are).
void zernike_phase(std::span<const double> coeffs, int first_j, const PupilGrid& grid,
                   std::span<double> phase);

}  // namespace vkjr2::sim
