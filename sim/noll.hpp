// Kolmogorov statistics of Noll-Zernike coefficients (Noll 1976), their
// Cholesky factor, a portable seeded Gaussian generator, and the conversion of
// tilt coefficients to angles. Derivations: docs/sim.md.
//
// All covariances are for D/r0 = 1 (multiply by (D/r0)^(5/3)); coefficients
// are in radians of phase at the wavelength r0 is given for.
#pragma once

#include <cstdint>
#include <random>
#include <span>
#include <vector>

namespace vkjr2::sim {

// Kolmogorov phase structure function D_φ(r) = C_D (r/r0)^(5/3) with the exact
// C_D = 2 [(24/5) Γ(6/5)]^(5/6) ≈ 6.8839 (Fried 1965; "6.88").
double structure_function_constant();
// Phase PSD Φ(f) = c_Φ r0^(−5/3) f^(−11/3), f in cycles per metre, with
// c_Φ = Γ(11/6)² / (2 π^(11/3)) · [(24/5) Γ(6/5)]^(5/6) ≈ 0.02290 ("0.023"),
// the value for which the PSD reproduces D_φ above.
double phase_psd_constant();
// Noll's constant K in ⟨a_i a_j⟩ for D/r0 = 1, derived from the PSD above:
// K = c_Φ Γ(14/3) π^(8/3) 2^(−5/3) = Γ(14/3) Γ(11/6)² [(24/5)Γ(6/5)]^(5/6) / (2^(8/3) π)
// ≈ 2.2461. (Noll printed 2.2698, which is 1.06 % high; see docs/sim.md.)
double noll_constant();
inline constexpr double kNollPrintedConstant = 2.2698;

// ⟨a_i a_j⟩ for D/r0 = 1, i, j ≥ 2 (Noll 1976 eq. 25 with noll_constant()).
// Nonzero only for equal m and (m = 0 or i − j even).
double noll_covariance(int i, int j);
// (j_max − 1)² row-major matrix over modes 2..j_max.
std::vector<double> noll_covariance_matrix(int j_max = 36);

// Piston-removed phase variance over the aperture for D/r0 = 1:
// Δ1 = ½ C_D ⟨|x − x′|^(5/3)⟩ over pairs of points in a unit-diameter disk,
// by the closed form of that moment (≈ 1.0324; Noll's Table IV: 1.0299).
double piston_removed_variance();
// Noll's residual Δ_J = Δ1 − Σ_{j=2}^{J} ⟨a_j²⟩ after removing modes 1..J.
double noll_residual(int last_j);

// Lower-triangular L with L Lᵀ = a (n × n, row-major, symmetric). Throws
// InvalidArgument naming the failing pivot when a is not positive definite.
std::vector<double> cholesky(std::span<const double> a, int n);

// Seeded generator whose numbers depend only on the seed, not on the standard
// library: std::mt19937_64 (its output is fixed by the C++ standard), 53-bit
// uniforms, and Marsaglia's polar method for normals (std::normal_distribution
// is implementation-defined). Values agree across platforms up to the last-bit
// rounding of std::log.
class Rng {
 public:
  explicit Rng(std::uint64_t seed) : engine_(seed) {}
  double uniform();  // [0, 1), 53 random bits
  double normal();   // standard normal
  std::uint64_t bits() { return engine_(); }

 private:
  std::mt19937_64 engine_;
  double spare_ = 0;
  bool has_spare_ = false;
};

// Draws correlated Noll coefficients a_2..a_{j_max}: a = (D/r0)^(5/6) · L · n
// with L the Cholesky factor of noll_covariance_matrix(j_max) and n i.i.d.
// standard normals from Rng.
class NollSampler {
 public:
  explicit NollSampler(int j_max = 36);
  int j_max() const { return j_max_; }
  int modes() const { return j_max_ - 1; }
  const std::vector<double>& covariance() const { return cov_; }
  const std::vector<double>& cholesky_factor() const { return chol_; }
  // out: modes() values, out[k] = a_{k+2}.
  void sample(Rng& rng, double d_over_r0, std::span<double> out) const;
  // count draws, row-major (count × modes()).
  std::vector<double> sample(Rng& rng, double d_over_r0, int count) const;

 private:
  int j_max_;
  std::vector<double> cov_;
  std::vector<double> chol_;
};

// Angle of arrival of a Noll tilt: for a phase a·Z2 = a·2ρ cosθ (ρ = r/R), the
// wavefront slope is (λ/2π)·∂φ/∂x = (λ/2π)(2a/R) = (2/π) a λ/D radians. The
// same for Z3 along y.
double tilt_angle_rad(double a_tilt, double wavelength_m, double aperture_m);
// (sim/tilt.hpp has the same for a channel of the simulation parameters.)
// One-axis G-tilt (aperture-averaged phase gradient: the PSF centroid, what a
// camera sees) angle variance c_G (λ/D)² (D/r0)^(5/3) rad². By the divergence
// theorem the mean x-gradient is (1/A)∮ φ n_x ds, so its variance is
// −(1/2A²)∮∮ n_x n_x' D_φ(|s − s'|) ds ds' = −(π R²/2A²) ∫_0^{2π} cos u
// D_φ(2R |sin(u/2)|) du (the ∮ n_x ds = 0 removes the constant of the
// covariance); c_G ≈ 0.1698, 0.933 of the Z-tilt's 0.1819 (docs/sim.md §3).
double g_tilt_constant();

}  // namespace vkjr2::sim
