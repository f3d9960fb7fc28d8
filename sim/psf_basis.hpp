// Wave-optics PSFs of Zernike-aberrated pupils and their principal-component
// basis (the "PSF basis" the P2S network predicts coefficients for).
//
// PSF = |FFT_N(P · exp(i Σ_{j≥4} a_j Z_j))|², sampled at the detector pitch p:
// the focal-plane sample of an N-point FFT over a pupil of diameter_px samples
// is λ f·diameter_px/(N D), so N = 2·q·diameter_px with the Nyquist ratio
// q = λ f/(2 D p) (docs/sim.md §2). Tilt (a_2, a_3) and piston are excluded:
// tilt is applied separately as a warp. Choices and measured numbers:
// docs/p2s.md.
#pragma once

#include <vkjr2/runtime/device.hpp>
#include <vkjr2/sim/noll.hpp>
#include <vkjr2/sim/zernike.hpp>

#include <cstdint>
#include <memory>
#include <span>
#include <vector>

namespace vkjr2::sim {

struct PsfSampling {
  double nyquist = 0.61;     // q = λ f / (2 D p), > 0
  int size = 33;             // S: odd side of the centred crop
  int j_max = 36;            // aberrations a_4..a_{j_max} (≥ 4)
  double min_pupil_px = 64;  // the pupil gets at least this many samples across
};

// The FFT geometry chosen for a sampling. The PSF at the pitch is every
// `oversample`-th bin of an fft_size-point FFT (oversample > 1 only when
// q < 0.5, where the pupil would not fit in 2q·diameter_px samples).
struct PsfGrid {
  int fft_size = 0;        // an FFT-supported length, a multiple of oversample
  int oversample = 1;      // bins per detector pixel
  double diameter_px = 0;  // fft_size / (2 q oversample): pupil samples across
  int period_px() const { return fft_size / oversample; }  // the sampled PSF's period
};

// Smallest grid with diameter_px ≥ min_pupil_px and period_px ≥ size. Throws
// InvalidArgument on a bad sampling (q ≤ 0 or not finite, even or < 1 size,
// j_max < 4 or > kMaxZernikeModes).
PsfGrid psf_grid(const PsfSampling& sampling);

// Computes batches of PSFs: pupil fields on the host (double, then float),
// batched c2c FFTs on the device (kernels::FftPlan), |·|², centring and crop
// on the host. One thread at a time per object (FFT plans are built on first use).
class WavePsf {
 public:
  WavePsf(const Device& device, const PsfSampling& sampling);
  ~WavePsf();
  WavePsf(const WavePsf&) = delete;
  WavePsf& operator=(const WavePsf&) = delete;
  WavePsf(WavePsf&&) noexcept;
  WavePsf& operator=(WavePsf&&) noexcept;

  const PsfSampling& sampling() const;
  const PsfGrid& grid() const;
  int modes() const;  // j_max − 3 coefficients per PSF

  // coeffs: count × modes() radians (row-major, a_4 first); psfs: count × S²,
  // row-major S×S crops centred on the optical axis at (S/2, S/2), each
  // summing to 1. energy_in_crop, when not empty (count values): the fraction
  // of one period of the pitch-sampled PSF that falls inside the crop.
  void compute(std::span<const double> coeffs, std::span<float> psfs,
               std::span<double> energy_in_crop = {}) const;
  std::vector<float> compute(std::span<const double> coeffs) const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

// count sets of a_4..a_{j_max} (count × (j_max − 3), row-major): each draws
// D/r0 uniform in [d_over_r0_min, d_over_r0_max], then a_2..a_{j_max} from
// `noll`, and drops the tilts a_2, a_3.
std::vector<double> draw_aberrations(Rng& rng, const NollSampler& noll, double d_over_r0_min,
                                     double d_over_r0_max, int count);
// The first `keep` columns of a row-major matrix with `columns` columns (the
// inputs a_4..a_{j_max} of draws that go on to a_{residual_j_max}).
std::vector<double> leading_columns(std::span<const double> rows, int columns, int keep);

struct PsfBasis {
  int size = 0;                  // S (odd)
  std::vector<float> kernels;    // [K, S, S]: kernels[0] = mean PSF (sum 1), then PCs
                                 // (unit L2 norm, sorted by variance)
  std::vector<float> variances;  // [K]: 0 for the mean, then the PC eigenvalues
  double nyquist = 0;            // the sampling it was made for
  int j_max = 36;                // coefficients a_4..a_{j_max} are the P2S input
  int count() const;             // K
};

struct PsfBasisConfig {
  int size = 33;               // S, odd
  int count = 100;             // K: the mean + K − 1 principal components
  int samples = 2000;          // M training PSFs
  double d_over_r0_min = 0.5;  // D/r0 of each draw, uniform in [min, max]
  double d_over_r0_max = 8.0;
  std::uint64_t seed = 1;
  double min_pupil_px = 64;
  // The PSFs also carry a_{j_max+1}..a_{residual_j_max}, drawn from Noll's
  // statistics but not P2S inputs, so that the basis (and the network trained
  // on the same kind of PSFs) represents E[PSF | a_4..a_{j_max}]: the blur of
  // the modes a j_max-mode simulator leaves out, which 36 modes would
  // otherwise miss (the short-exposure MTF at r = 0.1 D would be 9 % high at
  // D/r0 = 3; docs/p2s.md). ≤ j_max: none.
  int residual_j_max = kMaxZernikeModes;
};

// The PCA of `samples` (M × S² PSFs, M ≥ 2): ψ_0 = their mean, ψ_1..ψ_{K−1}
// the top eigenvectors of the sample covariance (1/(M − 1)) of the centred
// PSFs (through the M × M Gram matrix when M < S²), each of unit norm with its
// largest-magnitude entry positive. Throws InvalidArgument when K − 1 exceeds
// min(M − 1, S²).
PsfBasis psf_basis_from_samples(std::span<const float> samples, int size, int count, double nyquist,
                                int j_max);

// Draws config.samples PSFs (seeded) at `nyquist` and returns their basis.
// The PSFs include the residual modes of config.residual_j_max.
PsfBasis make_psf_basis(const Device& device, double nyquist, int j_max,
                        const PsfBasisConfig& config);

// β of each PSF (count × S² in, count × K out): β_0 = 1, β_k = ⟨h − ψ_0, ψ_k⟩.
std::vector<float> project(const PsfBasis& basis, std::span<const float> psfs);
// Σ_{k<terms} β_k ψ_k per row of betas (count × K in, count × S² out); terms
// ≤ 0 means all K.
std::vector<float> reconstruct(const PsfBasis& basis, std::span<const float> betas, int terms = 0);

// ‖a − b‖₂ / ‖b‖₂ per image of `image_size` values, averaged over the images.
double mean_relative_l2(std::span<const float> a, std::span<const float> b, int image_size);

}  // namespace vkjr2::sim
