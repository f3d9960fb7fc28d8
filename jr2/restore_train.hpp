// Training the restorer on clips our simulator makes on the fly
// (docs/restoration.md, `vkjr2 restore-train`).
//
// Data: clip k is a pure function of (seed, k): a clean training image,
// scaled by a random factor, cropped at a random place to crop² pixels and
// maybe mirrored, then degraded into T frames by the simulator at a D/r0
// drawn log-uniformly in the configured range, with its own simulator seed.
// A pool of `pool` clips is kept; every step replaces the `refresh` oldest
// with the next clips, and the batch is drawn from the pool (rng(seed,
// step)). Since the pool at step s holds exactly clips s·refresh ..
// s·refresh + pool − 1, a resumed run rebuilds it and goes on bit-exactly.
//
// Loss: Charbonnier (ε = 1e-3) between the restored reference frame and the
// clean crop; with explicit_weight > 0 (explicit modeling, after PiRN) plus
// that weight × the Charbonnier distance between the restored frame
// re-degraded by the simulator with the same draws that made the input
// reference frame (its flow and β maps, kept with the clip) and that input
// frame. AdamW with linear warm-up and cosine decay, global gradient
// norm clipping. The held-out set: fixed clips from the validation images
// (centre crops, strengths spread over the range), scored by PSNR/SSIM of the
// restored and of the degraded reference frame.
#pragma once

#include <vkjr2/jr2/restorer.hpp>
#include <vkjr2/nets/autograd.hpp>
#include <vkjr2/nets/optimizer.hpp>
#include <vkjr2/runtime/host_tensor.hpp>
#include <vkjr2/sim/blur_model.hpp>

#include <cstdint>
#include <filesystem>
#include <functional>
#include <map>
#include <memory>
#include <string>
#include <vector>

namespace vkjr2::jr2 {

struct RestoreTrainOptions {
  RestorerConfig net;
  int crop = 64;  // training clips are crop² pixels (a multiple of 2^levels)
  int batch = 8;
  int steps = 1000;
  float lr = 1e-3f, min_lr = 1e-6f, weight_decay = 0.f;
  int warmup_steps = 50;
  float clip_grad_norm = 0.5f;                // 0: no clipping
  double d_over_r0_lo = 1, d_over_r0_hi = 8;  // weak to strong (jr2/benchmark.hpp)
  double scale_lo = 0.4, scale_hi = 1.0;      // crop side / the image's shorter side
  int pool = 64, refresh = 1;
  int val_clips = 8;
  std::uint64_t seed = 1;
  // Weight of the re-degradation consistency loss (0: internalizing only).
  float explicit_weight = 0.f;
  // The simulator's high-order modes correlated across the field (false:
  // the simpler simulator of sim::FieldOptions::correlate_high_order).
  bool correlate_high_order = true;

  // Throws InvalidArgument naming the option and the fix.
  void validate() const;
};

// A clean image: H×W×3 RGB, 0..255 (runtime/image.hpp).
struct TrainImage {
  std::string name;
  HostTensor rgb;
};

// A held-out clip's clean frame: the centre window of half the image's
// shorter side (at least `size`), resampled to size² as [3, size, size]
// planes in 0..1 (box-prefiltered bilinear samples). rgb: H×W×3, 0..255.
std::vector<float> held_out_crop(const HostTensor& rgb, int size);

// The simulator's frame formation for fixed turbulence as a differentiable
// op of the image (sim::Simulator::frame without noise):
//   y = Σ_k ψ_k ⊛ (β_k ⊙ W(x; flow)) / Σ_k ψ_k ⊛ β_k
// x [B, C, H, W] with C ≤ 4; flow [B, 2, H, W] (Simulator::flow()); beta
// [B, K, H, W] (Simulator::beta(), shared by the channels); basis [K, S, S]
// (BlurModel::basis()). The gradient reaches x only: the maps are fixed draws.
nets::Var redegrade(nets::Tape& tape, const nets::Var& x, const Tensor& flow, const Tensor& beta,
                    const Tensor& basis);

struct RestoreStepReport {
  int step = 0;  // the step just taken (1-based)
  double loss = 0, lr = 0, grad_norm = 0;
  double consistency = 0;  // the consistency term (unweighted; 0 without explicit_weight)
  double sim_seconds = 0, train_seconds = 0;
};

struct RestoreEvalReport {
  int step = 0;
  double psnr_degraded = 0, psnr_restored = 0;
  double ssim_degraded = 0, ssim_restored = 0;
  double seconds = 0;
};

class RestoreTrainer {
 public:
  // train, val: at least one image each, every side ≥ options.crop. blur:
  // the simulator's models (sim::load_shipped_blur_models).
  RestoreTrainer(const Device& device, const RestoreTrainOptions& options,
                 std::vector<TrainImage> train, std::vector<TrainImage> val,
                 std::vector<std::shared_ptr<const sim::BlurModel>> blur);
  ~RestoreTrainer();
  RestoreTrainer(const RestoreTrainer&) = delete;
  RestoreTrainer& operator=(const RestoreTrainer&) = delete;

  // Fills the pool for the current step (the first train_step() does it
  // when not called): `progress(done, total)` after each clip.
  void prepare(const std::function<void(int, int)>& progress = {});
  RestoreStepReport train_step();
  RestoreEvalReport evaluate();
  int step() const noexcept;

  // A checkpoint: weights, AdamW state, the step and the options that fix
  // the data (a resume with other ones is refused, naming them).
  void save_checkpoint(const std::filesystem::path& path,
                       const std::map<std::string, std::string>& metadata = {}) const;
  void load_checkpoint(const std::filesystem::path& path);

  const Restorer& restorer() const;
  // The options as metadata strings (saved with every checkpoint and model).
  std::map<std::string, std::string> options_metadata() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace vkjr2::jr2
