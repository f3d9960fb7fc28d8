// Turbulence strength from the footage alone (docs/jr2.md §7): D/r0 of a
// video from its frame-to-frame tilt and the fluctuation of its blur.
//
// The frames are registered against their mean by dense optical flow
// (OpenCV's DIS in the command runner; here, measure_tilt: the Lucas–Kanade
// kernel of kernels/flow.hpp, twice, the second pass against the mean of the
// frames warped back by the first). The per-pixel temporal variance of the
// displacement, averaged over both axes, its median over the pixels whose
// window has enough texture, is the tilt variance σ² (pixels², one axis).
// The Z-tilt formula σ²_θ = 0.182 (λ/D)² (D/r0)^(5/3) (sim/tilt.hpp) with the
// optics' pixel scale turns it into a raw D/r0.
// A variance about the mean of T correlated frames is short of the true one by
// the factor 1 − (1/T)(1 + 2 Σ_k (1 − k/T) ρ^k) for an AR(1) tilt of
// frame-to-frame correlation ρ; the raw value is corrected by it. A
// calibration fitted on simulated videos of known D/r0,
// D/r0 = gain · raw^exponent (· blur^blur_exponent with the spectral cue
// below), takes out what the registration still biases (blur, noise,
// compression, the window's averaging).
#pragma once

#include <vkjr2/runtime/stream.hpp>
#include <vkjr2/sim/blur_model.hpp>
#include <vkjr2/sim/params.hpp>
#include <vkjr2/sim/simulator.hpp>

#include <cstdint>
#include <filesystem>
#include <map>
#include <span>
#include <string>
#include <vector>

namespace vkjr2::jr2 {

struct TiltOptions {
  int radius = 3;                // registration window: kernels::LucasKanade::radius
  int iterations = 5;            // Lucas–Kanade steps per pass
  int passes = 2;                // registrations against the (re-)averaged frames
  float min_eigenvalue = 2e-5f;  // windows flatter than this (0..1 intensities) are not used
  int border = 8;                // pixels from the edge that are not used
  // Throws InvalidArgument naming the option and the fix.
  void validate() const;
};

struct TiltMeasure {
  int frames = 0;
  // The one-axis temporal variance of the displacement, pixels²: the median
  // over the pixels used (robust to a moving object in part of the frame).
  double variance_px2 = 0;
  double mean_variance_px2 = 0;    // the mean over the pixels used
  double lag1_covariance_px2 = 0;  // the mean covariance between consecutive frames
  double coverage = 0;             // share of the frame's pixels used
};

// The tilt statistics of displacement fields flow [T, 2, H, W] (planar,
// pixels; frame t moved by flow_t registers onto the reference): the
// one-axis temporal variance and lag-1 covariance per pixel, over
// the pixels at least options.border from the edge whose texture[p]
// (the smaller eigenvalue of the reference's structure tensor, as
// texture_map gives it) reaches options.min_eigenvalue. Throws
// InvalidArgument when fewer than 2 % of the pixels qualify.
TiltMeasure tilt_statistics(std::span<const float> flow, int frames, int height, int width,
                            std::span<const float> texture, const TiltOptions& options);

// Per pixel, the smaller eigenvalue of the mean structure tensor ⟨g gᵀ⟩
// (central differences, the border row repeated) over the
// (2·radius + 1)² window clipped to the image, of a grey image (0..1).
std::vector<float> texture_map(std::span<const float> image, int height, int width, int radius);

// The checks every tilt measurement makes of T grey frames (T×H×W, 0..1):
// at least 2 frames, larger than the border on both sides, every pixel
// finite. Throws InvalidArgument naming the fault and the fix.
void check_grey_video(std::span<const float> pixels, int frames, int height, int width,
                      const TiltOptions& options);

// Measures the tilt of T grey frames ([T, 1, H, W], 0..1, T ≥ 2) on the
// stream's device by the Lucas–Kanade kernel (kernels/flow.hpp). Throws InvalidArgument for a frame
// smaller than the border and window, fewer than 2 frames, a non-finite pixel, or a video without
// texture enough to register (coverage below 2 %), naming the fix.
TiltMeasure measure_tilt(Stream& stream, const Tensor& frames, const TiltOptions& options = {});

// The factor by which the variance about the mean of `frames` samples of an
// AR(1) series of correlation rho falls short of its variance.
double correlated_variance_factor(int frames, double rho);

// The blur cue: how much the short-exposure spectrum fluctuates from frame to
// frame. In each square tile (Hann-windowed, its mean removed) the power in a
// band of spatial frequencies, fixed in units of the optics' cutoff D/λ, is
// taken per frame; the standard deviation over the frames of its log is the
// tile's fluctuation, the median over the tiles the video's. The scene's
// spectrum cancels in the log differences between frames of the same scene,
// so the cue does not depend on how sharp the scene is; a moving object
// changes a minority of the tiles.
struct SpectrumOptions {
  double band_lo = 0.10, band_hi = 0.17;  // the band, fractions of the cutoff D/λ
  int tile = 64, stride = 32;             // tile side and step, px (a smaller frame: one tile)
  // Throws InvalidArgument naming the option and the fix.
  void validate() const;
};

struct SpectrumMeasure {
  int frames = 0, tiles = 0;
  double band_lo_px = 0, band_hi_px = 0;  // the band in cycles per pixel
  double fluctuation = 0;  // median over the tiles of the sd over frames of log band power
};

// The spectral fluctuation of T grey frames (T×H×W, 0..1) under `optics`
// (pixel scale and first wavelength; its turbulence is not used). Throws
// InvalidArgument for fewer than 2 frames, a non-finite pixel, a band that
// holds fewer than 8 frequency bins of a tile, or frames without texture in
// the band.
SpectrumMeasure spectral_fluctuation(std::span<const float> grey, int frames, int height, int width,
                                     const sim::Params& optics,
                                     const SpectrumOptions& options = {});

struct TurbulenceCalibration {
  // D/r0 = gain · raw^exponent · blur^blur_exponent, where raw is the tilt's
  // D/r0 and blur the spectral fluctuation corrected to independent frames;
  // a cue the calibration does not use has exponent 0 and is not measured.
  double gain = 1.0, exponent = 1.0;
  double blur_exponent = 0.0;
  double tilt_correlation = 0.9;  // ρ the raw value is corrected with
  double blur_correlation = 0.6;  // ρ the fluctuation is corrected with
  TiltOptions tilt;
  SpectrumOptions spectrum;
  // The registration the fit was measured with: "dis" (OpenCV's DIS optical
  // flow, vkjr2 estimate's) or "lk" (measure_tilt). An estimate uses the same.
  std::string registration = "dis";
  std::map<std::string, std::string> metadata;  // what it was fitted on

  // The identity calibration (raw values, ρ = 0.9).
  static TurbulenceCalibration identity();
  bool uses_tilt() const noexcept { return exponent != 0.0; }
  bool uses_spectrum() const noexcept { return blur_exponent != 0.0; }
  // "tilt", "spectrum" or "tilt+spectrum".
  std::string cues() const;
  // Atomic write; the reader checks every key and names the file.
  void save(const std::filesystem::path& path) const;
  static TurbulenceCalibration load(const std::filesystem::path& path);
};

struct TurbulenceEstimate {
  TiltMeasure tilt;          // frames = 0 when the calibration does not use the tilt
  SpectrumMeasure spectrum;  // frames = 0 when the calibration does not use it
  double raw_d_over_r0 = 0;  // from the corrected tilt variance by the Z-tilt formula
  double blur = 0;           // the fluctuation corrected to independent frames
  double d_over_r0 = 0;      // calibrated, at the optics' first wavelength
  double r0_m = 0;           // D / (D/r0)
};

// D/r0 from a tilt variance through the Z-tilt formula, with the optics'
// pixel scale and first wavelength (optics.image and the turbulence of
// `optics` are not used) and the correlation correction.
double raw_d_over_r0(double variance_px2, int frames, const sim::Params& optics, double rho);

// The spectral fluctuation corrected for the frames' correlation ρ: divided by
// √(correlated_variance_factor(frames, ρ)).
double corrected_fluctuation(const SpectrumMeasure& spectrum, double rho);

// The calibrated estimate from the measured cues (each may be default, frames
// 0, when the calibration does not use it; one it uses must be measured).
TurbulenceEstimate estimate_turbulence(const TiltMeasure& tilt, const SpectrumMeasure& spectrum,
                                       const sim::Params& optics,
                                       const TurbulenceCalibration& calibration);
// The tilt-only form (a calibration that uses the spectrum throws).
TurbulenceEstimate estimate_turbulence(const TiltMeasure& tilt, const sim::Params& optics,
                                       const TurbulenceCalibration& calibration);
// The same, measured on the device frames [T, 1, H, W] by measure_tilt
// (calibration.registration must be "lk") and spectral_fluctuation.
TurbulenceEstimate estimate_turbulence(Stream& stream, const Tensor& frames,
                                       const sim::Params& optics,
                                       const TurbulenceCalibration& calibration);

// Least-squares fit of log D/r0 = log gain + exponent · log raw over pairs
// (raw, true D/r0). Throws InvalidArgument for fewer than 3 pairs, a
// non-positive value, or raw values that do not vary.
TurbulenceCalibration fit_calibration(std::span<const double> raw, std::span<const double> truth,
                                      const TiltOptions& tilt, double tilt_correlation,
                                      const std::string& registration);

// The fit of `base`'s cues (its exponents' zero pattern: a non-zero exponent
// is fitted, a zero one stays 0) in logs over the videos: raw[i] the tilt's
// raw D/r0, blur[i] the corrected fluctuation (either may be empty when its
// cue is not used), truth[i] the true D/r0. The options and correlations are
// base's. Throws InvalidArgument for fewer videos than 1 + the fitted terms, a
// non-positive value, or cues that do not vary independently.
TurbulenceCalibration fit_calibration(const TurbulenceCalibration& base,
                                      std::span<const double> raw, std::span<const double> blur,
                                      std::span<const double> truth);

// Frames as the estimator reads them: the mean of the channels of
// [T, C, H, W] host pixels in 0..range → [T, 1, H, W] 0..1.
std::vector<float> grey_frames(std::span<const float> rgb, int frames, int channels, int height,
                               int width, float range = 255.f);

// A simulated video with the tilt it was made with, for checking and
// calibrating estimates: `frames` frames of `scene` ([1, C, H, W], 0..1)
// through the simulator (params, options, the shipped or given blur models)
// from `seed`; grey [T, H, W] (0..1) and the simulator's own flow maps
// [T, 2, H, W] (the warp's sampling offsets, pixels).
struct SimulatedVideo {
  int frames = 0, height = 0, width = 0;
  std::vector<float> grey, flow;
};
SimulatedVideo simulate_video(const Device& device, const Tensor& scene, const sim::Params& params,
                              const sim::SimOptions& options,
                              const std::vector<std::shared_ptr<const sim::BlurModel>>& blur,
                              std::uint64_t seed, int frames);

// The shipped calibration (artifacts/turbulence_estimator.safetensors).
std::filesystem::path default_turbulence_calibration_path();

}  // namespace vkjr2::jr2
