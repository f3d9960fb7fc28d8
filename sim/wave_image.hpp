// Extended scenes through the wave-optics reference (Hardie et al., Opt.
// Eng. 56(7) 071502, 2017): point sources on a grid over the field share
// one set of phase screens (sim/wave_optics.hpp), each gets its PSF, and
// every scene pixel is imaged with the PSF interpolated bilinearly between
// its four nearest sources:
//   y(p) = Σ_q x(q) h_q(p − q) / Σ_q h_q(p − q),  h_q = Σ_k w_k(q) PSF_k
// (the scattering form with the same border normalization as the fast
// simulator). The PSFs keep their tilt (their displacement from the
// geometric image point), so this is tilt and blur at once. Propagation and
// PSFs run on the device (or, with WaveConfig::fft = FftBackend::fftw, on
// the CPU with FFTW); the sum over pixels on the host.
#pragma once

#include <vkjr2/runtime/device.hpp>
#include <vkjr2/sim/params.hpp>
#include <vkjr2/sim/wave_optics.hpp>

#include <functional>
#include <span>
#include <vector>

namespace vkjr2::sim {

struct WaveImageConfig {
  WaveConfig wave;
  // Spacing of the point sources in pixels (the grid spans the image with
  // sources on its corners). The fast simulator's field step is the matching
  // choice: both then resolve the PSF field equally finely.
  double source_step_px = 16;
  int psf_size = 0;  // S (odd); 0: the smallest odd size ≥ 8 × the seeing FWHM, within [9, 65]
};

struct WaveImageReport {
  int sources_y = 0, sources_x = 0, psf_size = 0;
  std::vector<WavePlan> plans;  // one per distinct channel wavelength
  double psf_seconds = 0, image_seconds = 0;
};

// x: [C, H, W] for params.image (batch 1). progress(done, total) is called
// after each row of sources.
std::vector<float> wave_image(const Device& device, const Params& params,
                              const WaveImageConfig& config, std::span<const float> x,
                              WaveImageReport* report = nullptr,
                              const std::function<void(int, int)>& progress = {});

}  // namespace vkjr2::sim
