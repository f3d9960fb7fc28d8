// Spatially and temporally correlated Zernike coefficient fields across the
// frame: the turbulence state of the fast simulator (docs/sim.md §6).
//
// Each mode j = 2..j_max is a unit-variance Gaussian field on a coarse grid
// over the image with the path-integrated angular correlation of
// sim/correlation.hpp, sampled by circulant embedding: the correlation is
// laid on a torus at least twice the grid, its FFT gives the eigenvalues λ,
// and a field is Re F⁻¹(√(λ/M) · w) for complex white seeds w (M = torus
// size). The fields are then mixed point by point by the Cholesky factor of
// Noll's covariance and scaled by (D/r0)^(5/6), so every point has Noll's
// inter-mode covariance exactly. For video the seeds evolve by AR(1),
// w_t = ρ w_{t−1} + √(1 − ρ²) n_t, with their own ρ for the tilts and for
// the high orders. FFTs, seeds and mixing run on the device.
#pragma once

#include <vkjr2/kernels/fft.hpp>
#include <vkjr2/runtime/stream.hpp>
#include <vkjr2/sim/correlation.hpp>
#include <vkjr2/sim/params.hpp>

#include <cstdint>
#include <memory>

namespace vkjr2::sim {

struct FieldOptions {
  // Highest Noll index sampled (0: params.zernike_modes; 3: tilts only,
  // which allows a much coarser grid).
  int j_max = 0;
  // Grid step: the largest step (px, ≤ max_step_px) at which every mode's
  // correlation along x and y is still ≥ min_step_correlation.
  int max_step_px = 16;
  double min_step_correlation = 0.9;
  // Lag-1 correlation of the seeds between consecutive frames (0: independent frames).
  double tilt_rho = 0.0;
  double high_order_rho = 0.0;
  // false: the high-order modes a_4.. are independent from one grid point to
  // the next (a white field; Noll's one-point covariance is kept), as in the
  // simulators that correlated only the tilts across the field. The tilts
  // stay correlated. A deliberately simpler simulator for fidelity studies
  // (docs/restoration.md, study 2).
  bool correlate_high_order = true;
};

class TurbulenceField {
 public:
  // Validates and derives params; channel 0's wavelength and D/r0 set the
  // coefficient units (radians of phase at that wavelength).
  TurbulenceField(const Device& device, const Params& params, const FieldOptions& options = {});
  ~TurbulenceField();
  TurbulenceField(const TurbulenceField&) = delete;
  TurbulenceField& operator=(const TurbulenceField&) = delete;

  // Fresh seeds from `seed`; the next frame() is frame 0 of a new sequence.
  void reset(std::uint64_t seed);
  // Records the next frame's fields into the stream: frame 0 after reset,
  // then one AR(1) step per call.
  void next(Stream& stream);

  int modes() const { return j_max_ - 1; }  // a_2..a_{j_max}
  int j_max() const { return j_max_; }
  int batch() const { return batch_; }
  int grid_h() const { return grid_h_; }
  int grid_w() const { return grid_w_; }
  // Spacing of the grid in image pixels (grid point (r, c) sits at pixel
  // (r · step_y, c · step_x); the last point is the last pixel).
  double step_y_px() const { return step_y_; }
  double step_x_px() const { return step_x_; }
  // Share of the embedding's eigenvalue mass that was negative and clipped
  // (0 = the sampled covariance is exact on the grid).
  double clipped_fraction() const { return clipped_; }
  const FieldCorrelation& correlation() const { return *correlation_; }

  // [B, modes, grid_h, grid_w]: plane k is a_{k+2} in radians (channel 0).
  const Tensor& coefficients() const { return coefficients_; }
  // [B, 2, grid_h, grid_w]: the image shift (x, y) in pixels from a_2, a_3
  // (positive a_2 moves the image toward +x; docs/sim.md §4).
  const Tensor& tilt_px() const { return tilt_; }
  std::int64_t frame_index() const { return frame_; }

 private:
  // FFT of each mode's correlation laid on the current torus: [modes, Mh, Mw, 2].
  std::vector<float> embedding_eigenvalues() const;
  Device device_;
  int j_max_, batch_;
  int grid_h_ = 1, grid_w_ = 1, torus_h_ = 1, torus_w_ = 1;
  double step_y_ = 0, step_x_ = 0, clipped_ = 0, ifov_rad_ = 0;
  FieldOptions options_;
  std::unique_ptr<FieldCorrelation> correlation_;
  std::unique_ptr<kernels::FftPlan> plan_;
  std::uint64_t seed_ = 0;
  std::int64_t frame_ = -1;
  bool seeded_ = false;
  float scale_ = 1, tilt_x_ = 1, tilt_y_ = 1;
  Tensor spectrum_;  // [modes·B, Mh, Mw, 2]: √(λ/M) twice per bin
  Tensor seeds_;     // [modes·B, Mh, Mw, 2]: complex white seeds, AR(1) state
  Tensor planes_;    // [modes·B, Mh, Mw, 2]: F⁻¹(spectrum ⊙ seeds)
  Tensor mix_;       // [modes, modes]: Cholesky factor of Noll's covariance
  Tensor coefficients_, tilt_;
};

}  // namespace vkjr2::sim
