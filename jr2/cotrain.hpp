// JR² co-optimization (docs/jr2.md, `vkjr2 cotrain`): the pretrained
// restorer fine-tuned with the face-recognition loss, back-propagated through
// the frozen recognizer and the differentiable alignment, while a frozen copy
// of the pretrained restorer (the teacher) keeps it restoring
// (self-distillation).
//
// Restore-first (the seed paper's method), per clip of the batch:
//   y (T degraded frames of the face window) → student R_s(y) → pixels
//   255·clamp(·, 0, 1) → 68 landmarks on the restored frame (constants) →
//   5 points → similarity onto the 150² template (Umeyama) → affine grid +
//   bilinear grid-sample (differentiable) → recognizer G (frozen) →
//   descriptor → AdaFace margin head over the training identities.
// Align-first: the 5 points come from the degraded reference frame, every
// frame is aligned first and the student restores the 150² aligned crop; the
// loss does not pass through the alignment.
//
//   L = CE(AdaFace(G(align(R_s(y)))), label) + λ · mean |R_t(y) − R_s(y)|
//
// λ = 0 is plain fine-tuning. The head's class centres start as the mean
// clean descriptor of each identity (the same alignment on its clean clips)
// and train with the student; G, the landmark net and the teacher are frozen.
//
// Data: paired faces are clean clips (the benchmark's 160² clips) that the
// simulator degrades on the fly, as restore-train does: clip k is a pure
// function of (seed, k) — the face, a jitter of the window, D/r0 log-uniform
// in the range, the simulator seed — kept in a pool refreshed every step, so
// a resumed run rebuilds it and goes on bit-exactly. Unpaired faces carry
// degraded frames only (e.g. wave-optics clips standing in for real footage):
// clip k is then a window of frames of a drawn face, and only the identity
// labels and self-distillation train the student.
#pragma once

#include <vkjr2/jr2/restorer.hpp>
#include <vkjr2/nets/adaface.hpp>
#include <vkjr2/nets/face_box.hpp>
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

enum class CoTrainOrder : std::uint8_t { restore_first, align_first };
const char* order_name(CoTrainOrder order);
// "restore-first" or "align-first"; throws InvalidArgument otherwise.
CoTrainOrder parse_order(const std::string& text);

// Which of the student's layers train (bit mask). For a restorer of L
// levels: early = intro, encoders.0 and downs.0 (full resolution); late =
// decoders.{L−1} and ending (full resolution, the output side); middle =
// everything else (the lower resolutions and the bottom).
enum LayerGroup : unsigned { kEarlyLayers = 1, kMiddleLayers = 2, kLateLayers = 4, kAllLayers = 7 };
// "all", or a comma list of early, middle, late; throws InvalidArgument.
unsigned parse_layer_groups(const std::string& text);
std::string layer_groups_name(unsigned groups);
// The group of a restorer parameter by its name ("encoders.0.0.conv1.weight").
unsigned layer_group_of(const std::string& parameter, int levels);

struct CoTrainOptions {
  CoTrainOrder order = CoTrainOrder::restore_first;
  float lambda = 10.f;  // weight of the self-distillation L1 (0: fine-tune; docs/jr2.md §4)
  unsigned layers = kAllLayers;  // the student's trainable layer groups
  int window = 128;              // the restored face window, window² pixels (multiple of 2^levels)
  int jitter = 8;                // the window's centre moves up to ±jitter pixels
  int batch = 8;                 // ≥ 2 (AdaFace's batch statistics)
  int steps = 100;
  float lr = 1e-4f, min_lr = 1e-6f, weight_decay = 0.f;
  int warmup_steps = 10;
  float clip_grad_norm = 1.f;                 // 0: no clipping
  double d_over_r0_lo = 1, d_over_r0_hi = 8;  // paired clips' turbulence
  int pool = 32, refresh = 1;
  int val_clips = 16;
  std::uint64_t seed = 1;
  nets::AdaFaceOptions adaface;

  // Throws InvalidArgument naming the option and the fix.
  void validate() const;
};

// A training face. Paired: `clean` is an H×W×3 clip (0..255). Unpaired:
// `clean` is empty and `frames` holds its degraded frames (H×W×3 each, at
// least the restorer's T). Every face of a run has the same clip size.
struct CoTrainFace {
  std::string identity;
  std::string source;  // where it came from (messages, metadata)
  HostTensor clean;
  std::vector<HostTensor> frames;
  bool paired() const noexcept { return !clean.values.empty(); }
};

struct CoTrainStepReport {
  int step = 0;                                        // the step just taken (1-based)
  double loss = 0, recognition = 0, distillation = 0;  // distillation unweighted
  double lr = 0, grad_norm = 0;
  double sim_seconds = 0, train_seconds = 0;
  // Wall time of the step's stages (student, teacher, landmarks, alignment +
  // recognizer + head forward, backward, optimizer), seconds.
  double student_s = 0, teacher_s = 0, landmarks_s = 0, recognize_s = 0, backward_s = 0,
         update_s = 0;
};

// The held-out clips (fixed realizations of the training faces) scored by the
// student, the teacher and without restoration: rank-1 identification against
// the clean class centres, the mean cosine to the own centre, and (paired
// clips) PSNR/SSIM of the restored window against the clean one.
struct CoTrainEvalReport {
  int step = 0;
  struct Row {
    double top1 = 0, genuine_cos = 0;
    double psnr = 0, ssim = 0;  // NaN without clean frames
  };
  Row student, teacher, degraded;
  double seconds = 0;
};

class CoTrainer {
 public:
  // pretrained: the restorer file that is both the teacher and the student's
  // start. faces: at least 2 identities; val faces are the held-out clips'
  // sources (may be the same faces: other realizations; paired or not,
  // whatever the training faces are), each of a training identity. blur:
  // the simulator's models (for paired faces).
  CoTrainer(const Device& device, const CoTrainOptions& options,
            const std::filesystem::path& pretrained, std::vector<CoTrainFace> faces,
            std::vector<CoTrainFace> val, std::vector<std::shared_ptr<const sim::BlurModel>> blur);
  ~CoTrainer();
  CoTrainer(const CoTrainer&) = delete;
  CoTrainer& operator=(const CoTrainer&) = delete;

  // Detects the faces, computes the class centres and fills the pool
  // (train_step() does it when not called): progress(done, total) per clip.
  void prepare(const std::function<void(int, int)>& progress = {});
  CoTrainStepReport train_step();
  CoTrainEvalReport evaluate();
  int step() const noexcept;

  // The identities in class order.
  const std::vector<std::string>& identities() const;
  // The unpaired training clips left out because the detector found no face
  // in their mean frame nor in any frame (the constructor looks), and the
  // identities left without a clip (their held-out faces are left out too).
  const std::vector<std::string>& faceless_clips() const;
  std::vector<std::string> faceless_identities() const;
  // Parameters that train (student's groups + the head's centres).
  std::int64_t trainable_parameters() const;

  // Checkpoint: student, head (centres and norm statistics), Adam state and
  // step; the options that fix the run are checked on load (naming them).
  void save_checkpoint(const std::filesystem::path& path,
                       const std::map<std::string, std::string>& metadata = {}) const;
  void load_checkpoint(const std::filesystem::path& path);

  const Restorer& student() const;
  const nets::AdaFaceHead& head() const;
  // The options as metadata strings ("cotrain.*", plus the restorer's).
  std::map<std::string, std::string> options_metadata() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace vkjr2::jr2
