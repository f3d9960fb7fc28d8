// Angular correlation of Noll-Zernike coefficients across the field of view:
// how a_j seen from two scene points an angle θ apart are correlated, from
// the Kolmogorov spectrum integrated along the path (Takato & Yamaguchi,
// JOSA A 12, 958 (1995); Chimitt & Chan, Opt. Eng. 59(8) 2020 for the tilts).
// Derivation and conventions: docs/sim.md §5.
//
// One layer. A layer at distance z from the scene is crossed by the cone
// from each scene point to the aperture: a footprint of diameter D_z = D z/L
// (spherical wave; D for a plane wave), and two scene points an angle θ apart
// have footprints θ (L − z) apart, s = θ (L − z)/D_z footprint diameters.
// For modes of equal (n, m) and parity, with u = 2π·(spatial frequency)·R_z,
//   ⟨a_j(0) a_j(s)⟩ ∝ ∫₀^∞ u^(−14/3) J_{n+1}(u)² [J_0(2su) + ε (−1)^m J_{2m}(2su) cos 2mα] du,
// ε = +1 for cos modes, −1 for sin modes, no J_{2m} term for m = 0; α is the
// direction of the separation from +x (columns) toward +y (rows). So an
// x-tilt (Z2) decorrelates faster along x (longitudinal) than along y.
//
// The path. Layers add independently, each weighted by its share of the mode
// variance, Cn²(z) (z/L)^(5/3) (spherical; Cn² for a plane wave).
#pragma once

#include <vkjr2/sim/params.hpp>

#include <vector>

namespace vkjr2::sim {

// The one-layer integral G_{n,ν}(s) = ∫₀^∞ u^(−14/3) J_{n+1}(u)² J_ν(2su) du,
// ν = 0 or ν = 2m with m ≥ 1, n ≥ 1, s ≥ 0. Tabulated on first use (radial
// orders up to 20, s up to 100 by quadrature, beyond by the leading
// small-u asymptote, see docs/sim.md) and interpolated.
double layer_integral(int n, int nu, double s);
// The same by direct quadrature, no table (slow; for tests).
double layer_integral_direct(int n, int nu, double s);

// Normalized one-layer correlation of mode j at separation s (footprint
// diameters) in direction α (rad): 1 at s = 0.
double layer_correlation(int j, double s, double alpha_rad);

// Path-integrated angular correlation of modes 2..j_max for one set of
// parameters, tabulated once (a 1-D table per (n, ν) over θ) and then cheap
// to evaluate anywhere.
class FieldCorrelation {
 public:
  // max_angle_rad: the largest separation that will be asked for.
  FieldCorrelation(const Params& params, int j_max, double max_angle_rad);
  int j_max() const { return j_max_; }
  double max_angle_rad() const { return max_angle_; }
  // Normalized correlation of a_j between two field points separated by
  // (dx, dy) radians (x along columns, y along rows); 1 at (0, 0).
  double operator()(int j, double dx_rad, double dy_rad) const;

 private:
  double table(int n, int nu, double theta) const;  // path-integrated, normalized by G_{n,0}(0)
  int j_max_;
  double max_angle_;
  double step_;  // θ spacing of the tables
  int n_max_;
  // tables_[n][nu / 2] over θ = k · step_, k = 0..count.
  std::vector<std::vector<std::vector<double>>> tables_;
};

}  // namespace vkjr2::sim
