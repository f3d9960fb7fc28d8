// P2S ("phase to space"): an MLP from Zernike aberrations a_4..a_J (radians)
// to the coefficients β_1..β_{K−1} of the PSF in a PsfBasis, so that a PSF is
// ψ_0 + Σ_k β_k ψ_k without a wave-optics FFT. Trained here on wave-optics PSFs
// (sim/psf_basis.hpp) and stored with its basis in one safetensors file.
//
// Loss: MSE on β (in units of the output scale). The ψ_k are orthonormal, so
// this is the L2 error of the reconstructed PSF inside the basis' span (the
// PCA truncation error is the same for every prediction and adds nothing to
// the gradient), at a fraction of the cost of reconstructing PSFs. Measured
// accuracy and timings: docs/p2s.md.
#pragma once

#include <vkjr2/nets/layers.hpp>
#include <vkjr2/sim/params.hpp>
#include <vkjr2/sim/psf_basis.hpp>

#include <cstdint>
#include <filesystem>
#include <functional>
#include <memory>
#include <span>
#include <string>
#include <vector>

namespace vkjr2::sim {

struct P2sNetConfig {
  int j_max = 36;   // inputs a_4..a_{j_max}: j_max − 3 of them
  int count = 100;  // K of the basis: K − 1 outputs
  int hidden = 200;
  // Inputs are divided by σ_j(D/r0 = 1) · input_d_over_r0^(5/6), σ_j² =
  // noll_covariance(j, j): unit scale at this D/r0.
  double input_d_over_r0 = 4.0;
  // β̂ = output_scale · (last layer); the basis' largest PC std is a good value.
  float output_scale = 1.f;
  std::uint32_t seed = 1;
};

// The config for a basis: its j_max and K, output_scale = √variances[1].
P2sNetConfig p2s_config_for(const PsfBasis& basis);

// (J − 3) → hidden → hidden → (K − 1), LeakyReLU(0.2) after the hidden layers.
class P2sNet : public nets::Module {
 public:
  P2sNet(const Device& device, const P2sNetConfig& config);

  const P2sNetConfig& config() const noexcept { return config_; }
  int inputs() const noexcept { return config_.j_max - 3; }
  int outputs() const noexcept { return config_.count - 1; }

  // coeffs [P, J − 3] radians → β_1..β_{K−1} [P, K − 1] (β_0 = 1 is implicit).
  nets::Var forward(nets::Tape& t, const nets::Var& coeffs) const;
  // The same before the output scale: β̂ / output_scale (what training fits).
  nets::Var forward_normalized(nets::Tape& t, const nets::Var& coeffs) const;

  nets::Linear& l1;
  nets::Linear& l2;
  nets::Linear& l3;
  nets::Var input_scale;  // buffer [J − 3]: 1 / (σ_j · input_d_over_r0^(5/6))

 private:
  P2sNetConfig config_;
};

// β_0..β_{K−1} (count × K, β_0 = 1) for count rows of a_4..a_J (count × (J − 3)).
std::vector<float> predict_betas(const Device& device, const P2sNet& net,
                                 std::span<const double> coeffs);

struct P2sProgress {
  std::string stage;  // "basis", "data", "train", "test"
  int done = 0;
  int total = 0;
  double loss = 0;  // train: the step's loss
};
using P2sProgressFn = std::function<void(const P2sProgress&)>;

struct P2sTrainConfig {
  int steps = 4000;
  int batch = 256;
  int train_samples = 32768;  // wave-optics PSF/β pairs drawn for training
  int test_samples = 512;     // held out (another seed)
  float lr = 5e-3f;
  float min_lr = 2e-5f;
  std::uint32_t warmup_steps = 100;
  double d_over_r0_min = 0.5;
  double d_over_r0_max = 8.0;
  std::uint64_t seed = 2;  // aberrations and batch order; the test set uses seed + 1
  double min_pupil_px = 64;
  // The target PSFs also carry a_{j_max+1}..a_{residual_j_max} (not inputs):
  // the network learns E[PSF | a_4..a_{j_max}] (PsfBasisConfig::residual_j_max).
  int residual_j_max = kMaxZernikeModes;
};

struct P2sTrainReport {
  int steps = 0;
  double final_loss = 0;       // mean normalized β MSE over the last ≤ 50 steps
  double test_p2s_rel_l2 = 0;  // held out: ‖ψ_0 + Σ β̂_k ψ_k − h‖ / ‖h‖, mean over PSFs
  double test_pca_rel_l2 = 0;   // held out: the projection Σ β_k ψ_k alone
  double test_mean_rel_l2 = 0;  // held out: ψ_0 alone (the no-network baseline)
  double train_p2s_rel_l2 = 0;  // the P2S error on test_samples training pairs (overfit check)
  double basis_seconds = 0;     // make_p2s_artifact only
  double data_seconds = 0;
  double train_seconds = 0;
  double total_seconds = 0;
};

// Trains `net` (built for `basis`) on freshly drawn PSF/β pairs: Adam with a
// warm-up + cosine learning rate, batches drawn without replacement per epoch.
P2sTrainReport train_p2s(Device& device, P2sNet& net, const PsfBasis& basis,
                         const P2sTrainConfig& config, const P2sProgressFn& progress = {});

// ---- the artifact: basis + network in one safetensors file -------------------------
// Tensors "basis.kernels" [K, S, S], "basis.variances" [K], "p2s.<parameter>"
// and "p2s.input_scale"; metadata "format" = "vkjr2.p2s", "version", "size",
// "count", "nyquist", "j_max", "hidden", "input_d_over_r0", "output_scale".
struct P2sModel {
  PsfBasis basis;
  std::unique_ptr<P2sNet> net;
};

// Written atomically (temporary file + rename). Waits for the device.
void save_p2s_model(const std::filesystem::path& path, const PsfBasis& basis, const P2sNet& net);
// Throws InvalidArgument naming the file and what is wrong (unreadable or
// truncated, not a P2S model, missing or extra tensors, wrong shapes, NaN).
P2sModel load_p2s_model(const Device& device, const std::filesystem::path& path);

struct P2sArtifactConfig {
  int channel = 0;  // whose Nyquist ratio the basis is made for
  PsfBasisConfig basis;
  P2sTrainConfig train;
  int hidden = 200;
  double input_d_over_r0 = 4.0;
  std::uint32_t net_seed = 1;
};

// derive(params) → basis at channel's Nyquist ratio with j_max =
// params.zernike_modes → train → save to `out`. The report includes the
// basis time.
P2sTrainReport make_p2s_artifact(Device& device, const Params& params,
                                 const P2sArtifactConfig& config, const std::filesystem::path& out,
                                 const P2sProgressFn& progress = {});

}  // namespace vkjr2::sim
