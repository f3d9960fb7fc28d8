// The restoration gate (docs/jr2.md §8; the seed paper's VIDCLS): decides per
// probe video whether restoring it is worth its cost.
//
// Two small heads read frozen features of the degraded probe (its template,
// the descriptors' norm, the detector's score, the share of frames where the
// face was tracked, the estimated D/r0 and a sharpness measure):
//   - the score head predicts the quality proxy: the cosine similarity of the
//     degraded template to the template of the same face seen clean;
//   - the rank head predicts the rank-change label
//     exp((r_raw − r_post)/r_raw − 1) ∈ (0, 1] (1/e: the mate's rank is
//     unchanged by restoration; above: better; below: worse), trained with
//     the seed paper's re-weighting f(m) of m = label − 1/e.
// A probe is restored when the predicted quality is below a threshold and the
// rank is not predicted to get worse (label ≥ 1/e − margin), or when the
// degraded probe has no template at all. Threshold and margin are chosen on
// a validation split, never on the split that is reported.
#pragma once

#include <vkjr2/jr2/faces.hpp>
#include <vkjr2/nets/autograd.hpp>
#include <vkjr2/runtime/stream.hpp>

#include <cstdint>
#include <filesystem>
#include <map>
#include <memory>
#include <span>
#include <string>
#include <vector>

namespace vkjr2::jr2 {

// What the gate reads of one degraded probe.
struct GateFeatures {
  bool acquired = false;          // the probe has a template
  std::vector<float> descriptor;  // the template (unit length; empty when not acquired)
  double descriptor_norm = 0;     // mean L2 norm of the tracked frames' raw descriptors
  double detector_score = 0;      // mean detector score of the tracked frames
  double tracked_share = 0;       // tracked frames / sampled frames
  double d_over_r0 = 0;           // estimated from the footage (vkjr2 estimate)
  double sharpness = 0;           // gate_sharpness, mean over the sampled frames
};

// The number of summary features (everything but the descriptor) and their
// names, in the order of gate_feature_vector.
inline constexpr int kGateSummaryFeatures = 5;
std::vector<std::string> gate_feature_names(bool with_descriptor);
// [norm, score, tracked share, log D/r0, sharpness] (+ the 128 descriptor
// values, zeros when not acquired).
std::vector<float> gate_feature_vector(const GateFeatures& f, bool with_descriptor);

// Sharpness of a grey image (H×W, any range) inside the box [x0, x1) ×
// [y0, y1) (clipped to the image, at least 3×3 after clipping, else
// InvalidArgument): log of the mean squared 4-neighbour Laplacian over the
// box's variance (+1e-6); blur lowers it, contrast does not change it.
double gate_sharpness(std::span<const float> grey, int height, int width, int x0, int y0, int x1,
                      int y1);

// The rank-change label exp((r_raw − r_post)/r_raw − 1) of ranks ≥ 1
// (InvalidArgument otherwise).
double rank_change_label(int rank_raw, int rank_post);
// The seed paper's re-weighting f(m) = −1.25 + N(m; −0.25, 0.2²) +
// N(m; −1/e, 0.18²) + N(m; 1 − 1/e, 0.3²) of m = label − 1/e, N the normal
// density. It is negative on part of the range (f(0.24) ≈ −0.58: a rank 2
// made rank 1), where a loss weight cannot be: the rank head's sample
// weight is max(f(m), floor).
double rank_label_reweighting(double m);

// One probe of a labelled split: its features and what restoring it did.
struct GateSample {
  std::string file, strength;
  bool mated = false;
  GateFeatures features;
  double quality = 0;  // cosine(degraded template, clean template); used when acquired
  // The mate's rank among the gallery (1 = first; the gallery's size when
  // there is no template) degraded and restored; 0 for a non-mated probe.
  int rank_raw = 0, rank_post = 0;
};

struct GateTrainOptions {
  // Feed the 128 template values to the heads too. Off by default: with a
  // benchmark's hundred-odd labelled probes the heads fit the template's
  // noise (docs/jr2.md §8).
  bool descriptor = false;
  int hidden = 16;   // hidden units of each head (one ReLU layer)
  int steps = 1500;  // full-batch AdamW steps
  float lr = 3e-3f;
  float weight_decay = 1e-2f;
  float weight_floor = 0.05f;  // the smallest rank-sample weight
  std::uint32_t seed = 1;
  // Throws InvalidArgument naming the option and the fix.
  void validate() const;
};

struct GatePrediction {
  double quality = 0;     // the score head
  double rank_label = 0;  // the rank head, in (0, 1)
  bool restore = false;
};

// What a choice of threshold and margin does on a labelled split.
struct GateOutcome {
  double quality_threshold = 0, rank_margin = 0;
  std::size_t probes = 0, restored = 0, mated = 0;
  double mrr_degraded = 0, mrr_restored = 0, mrr_gated = 0;  // mean reciprocal rank of the mate
  std::size_t rank1_degraded = 0, rank1_restored = 0, rank1_gated = 0;
};

class Gate {
 public:
  // Trains both heads on `train` on the device (the score head on the
  // acquired probes, the rank head on the acquired mated ones). Throws
  // InvalidArgument when there are fewer than 3 of either, or the
  // features are not finite.
  static Gate train(const Device& device, std::span<const GateSample> train,
                    const GateTrainOptions& options);

  // The heads' outputs and the decision for each probe.
  std::vector<GatePrediction> predict(Stream& stream, std::span<const GateFeatures> probes) const;
  // The same, one probe.
  GatePrediction predict(Stream& stream, const GateFeatures& probe) const;
  // The decision from the heads' outputs at a threshold and margin.
  static bool decide(bool acquired, double quality, double rank_label, double quality_threshold,
                     double rank_margin);

  // Chooses the threshold and margin on a labelled split (validation): the
  // pair whose gated templates give the mated probes the highest mean
  // reciprocal rank; among equals, the one that restores fewest probes.
  // Candidates: every predicted quality (and ±∞) × margins {0, 0.05, 0.1,
  // 0.2, 1}. Returns what the chosen pair does there.
  GateOutcome choose_thresholds(Stream& stream, std::span<const GateSample> validation);
  // What the current threshold and margin do on a labelled split.
  GateOutcome outcome(Stream& stream, std::span<const GateSample> samples) const;

  double quality_threshold() const noexcept { return quality_threshold_; }
  double rank_margin() const noexcept { return rank_margin_; }
  void set_thresholds(double quality_threshold, double rank_margin);
  const GateTrainOptions& options() const noexcept { return options_; }
  // The alignment whose template and descriptors the features are read from.
  AlignMode align() const noexcept { return align_; }
  void set_align(AlignMode align) noexcept { align_ = align; }
  // Free-form provenance (training command, data, restorer, alignment):
  // saved and loaded with the heads.
  std::map<std::string, std::string> metadata;

  // Atomic write; the loader checks every key and shape and names the file.
  void save(const std::filesystem::path& path) const;
  static Gate load(const Device& device, const std::filesystem::path& path);

  Gate(Gate&&) noexcept;
  Gate& operator=(Gate&&) noexcept;
  ~Gate();

 private:
  struct Heads;
  Gate(std::unique_ptr<Heads> heads, GateTrainOptions options);
  nets::Var forward(nets::Tape& tape, int head, const nets::Var& x) const;
  Tensor inputs(const Device& device, std::span<const GateFeatures> probes) const;

  std::unique_ptr<Heads> heads_;
  GateTrainOptions options_;
  double quality_threshold_ = 0, rank_margin_ = 0;
  AlignMode align_ = AlignMode::similarity;
};

// Mean reciprocal rank, Rank-1 count and restored count of a split at the
// given decisions (one per sample).
GateOutcome gate_outcome(std::span<const GateSample> samples, std::span<const bool> restore);

}  // namespace vkjr2::jr2
