// The JR² evaluation: every probe's scores against the gallery, grouped per
// method × alignment × strength into the paper's metrics with bootstrap
// confidence intervals, and written as results.json, report.md and
// scores.csv (docs/eval.md).
#pragma once

#include <vkjr2/jr2/metrics.hpp>

#include <cstddef>
#include <limits>
#include <string>
#include <vector>

namespace vkjr2::jr2 {

// One probe video seen through one method and one alignment.
struct ProbeRecord {
  std::string method, align, strength, split;
  std::string file, identity;
  bool mated = false;
  bool acquired = false;       // it had a template; else every score is kNoTemplateScore
  std::vector<double> scores;  // per gallery identity (EvaluationInput::gallery order)
  int mate = -1;               // index of its identity in the gallery, or -1
  int frames = 0;              // sampled frames
  int single_scale = 0, multi_scale = 0, tracked = 0;  // frames where the face was found
  double psnr_db =
      std::numeric_limits<double>::quiet_NaN();  // of the sampled frames vs the clean clip
  double ssim = std::numeric_limits<double>::quiet_NaN();
  // Wall time of the method on this probe (decoding excluded), seconds.
  double seconds = std::numeric_limits<double>::quiet_NaN();
  int restored = -1;  // a gated method: 1 restored, 0 skipped; -1 not gated
};

struct EvaluationOptions {
  std::vector<double> fars = {1e-1, 1e-2, 1e-3, 1e-4};
  std::vector<double> fpirs = {1e-2, 1e-1};
  std::vector<std::size_t> ranks = {1, 5, 20};
  std::size_t fnir_max_rank = 1;  // R of FNIR(T, R)
  BootstrapOptions bootstrap;
};

struct RateWithInterval {
  OperatingPoint point;
  Interval interval;
};

// The metrics of one method × alignment × strength.
struct RowMetrics {
  std::string method, align, strength;
  std::size_t probes = 0, mated = 0, nonmated = 0, acquired = 0, identities = 0;
  std::size_t frames = 0, single_scale = 0, multi_scale = 0, tracked = 0;
  std::vector<RateWithInterval> tar;    // per EvaluationOptions::fars
  std::vector<Interval> rank;           // per EvaluationOptions::ranks
  std::vector<RateWithInterval> fnir;   // per EvaluationOptions::fpirs
  Interval psnr_db, ssim;               // mean over the probes that have them
  Interval seconds;                     // mean time per probe
  std::size_t gated = 0, restored = 0;  // probes a gate decided on; of them, restored
  std::vector<RocPoint> roc;
  std::vector<double> cmc;             // ranks 1..min(20, gallery)
  std::vector<OpenSetPoint> open_set;  // the FNIR–FPIR curve
};

struct Evaluation {
  std::vector<std::string> gallery;  // the enrolled identities, in score order
  std::string split;
  EvaluationOptions options;
  std::vector<ProbeRecord> records;
  std::vector<RowMetrics> rows;
};

// Groups the records (in their first-seen order of method, alignment,
// strength) and computes each row's metrics; the bootstrap resamples
// identities, then each identity's probes. Throws InvalidArgument on
// records whose scores do not match the gallery.
Evaluation evaluate(std::vector<std::string> gallery, std::string split,
                    std::vector<ProbeRecord> records, const EvaluationOptions& options);

// results.json: the setup, and per row every metric with its interval,
// the counts, and the curves.
std::string results_json(const Evaluation& e, const std::string& setup_json);
// report.md: one row per method × alignment × strength, every metric with
// its 95 % interval, and what a reader needs to weigh them.
std::string report_markdown(const Evaluation& e, const std::string& preamble);
// scores.csv: every comparison: method, align, strength, probe, gallery
// identity, score (cosine similarity), mated (the pair is genuine).
std::string scores_csv(const Evaluation& e);

}  // namespace vkjr2::jr2
