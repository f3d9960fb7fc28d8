// Face-recognition metrics of the JR² protocol (docs/eval.md has the
// definitions with worked examples): 1:1 verification (ROC, TAR at FAR),
// closed-set identification (CMC, Rank-k), open-set identification (FPIR,
// FNIR, FNIR at FPIR, TPIR, after NIST FRVT 1:N), templates, and bootstrap
// confidence intervals. Host code; scores are similarities (higher means more
// alike).
//
// Everything is computed from searches: one probe compared with every
// enrolled gallery identity. A mated search has its identity in the gallery
// (`mate` indexes its score); a non-mated search does not. Its verification
// pairs are the mate score (genuine) and every other score (impostor).
//
// Thresholds: an operating point at a target false-alarm rate p over N
// impostor scores takes t = the k-th largest impostor score, k = max(1,
// ⌊p·N⌋), and accepts a score s when s > t; so the achieved rate is at most
// (k − 1)/N ≤ p, ties at t counting as rejections. It is reported only when
// N ≥ ⌈1/p⌉ (fewer impostors cannot measure p).
#pragma once

#include <cstddef>
#include <cstdint>
#include <functional>
#include <limits>
#include <span>
#include <vector>

namespace vkjr2::jr2 {

// One probe searched against the gallery: scores[i] is its similarity to
// gallery identity i; mate is the index of its own identity, or -1 when it
// is not enrolled (a non-mated search).
struct Search {
  std::vector<double> scores;
  int mate = -1;
  bool mated() const noexcept { return mate >= 0; }
};

// Throws InvalidArgument (naming `what`) on a search with no scores, a mate
// index out of range, a non-finite score, or searches with different gallery
// sizes.
void check_searches(std::span<const Search> searches, const char* what);

// ---- 1:1 verification -------------------------------------------------------

struct VerificationScores {
  std::vector<double> genuine;   // the mate score of every mated search
  std::vector<double> impostor;  // every non-mate score of every search
};
VerificationScores verification_scores(std::span<const Search> searches);

// The ROC as scikit-learn's roc_curve(drop_intermediate=False) gives it: one
// point per distinct score, thresholds descending, preceded by (+inf, 0, 0);
// far = #{impostor ≥ threshold}/N_imp, tar = #{genuine ≥ threshold}/N_gen.
struct RocPoint {
  double threshold = 0, far = 0, tar = 0;
};
std::vector<RocPoint> roc_curve(std::span<const double> genuine, std::span<const double> impostor);

// An operating point at a target rate (see the header comment).
struct OperatingPoint {
  double target = 0;          // the target FAR or FPIR
  double value = 0;           // TAR, or FNIR (NaN when not reported)
  double achieved = 0;        // the FAR or FPIR actually reached (≤ target)
  double threshold = 0;       // t: a score is accepted when > t
  std::size_t negatives = 0;  // impostor scores / non-mated searches it came from
  bool reported = false;      // negatives ≥ ⌈1/target⌉
};
// TAR at a FAR: t from the impostor scores, TAR = #{genuine > t}/N_gen.
OperatingPoint tar_at_far(std::span<const double> genuine, std::span<const double> impostor,
                          double far);

// ---- closed-set identification ------------------------------------------------

// The mate's rank: 1 + #{non-mate scores ≥ mate score} (a tie ranks the mate
// below); 0 for a non-mated search.
std::size_t mate_rank(const Search& search);
// cmc[k − 1] = the share of mated searches whose mate rank ≤ k, k = 1..max_rank
// (Rank-k accuracy). Non-mated searches are left out; none mated: NaN.
std::vector<double> cmc(std::span<const Search> searches, std::size_t max_rank);

// ---- open-set identification (NIST FRVT 1:N) ----------------------------------

// FPIR(t) = share of non-mated searches whose best score is > t.
double fpir(std::span<const Search> searches, double threshold);
// FNIR(t, R) = share of mated searches whose mate ranks below R or scores ≤ t.
double fnir(std::span<const Search> searches, double threshold, std::size_t max_rank);
// FNIR at an FPIR: t from the best scores of the non-mated searches (as for
// TAR at FAR), then FNIR(t, max_rank). TPIR = 1 − FNIR.
OperatingPoint fnir_at_fpir(std::span<const Search> searches, double fpir_target,
                            std::size_t max_rank = 1);

// The DET-style curve: (fpir, fnir) at every distinct best non-mated score
// taken as the threshold, from the strictest (fpir 0) down.
struct OpenSetPoint {
  double threshold = 0, fpir = 0, fnir = 0;
};
std::vector<OpenSetPoint> open_set_curve(std::span<const Search> searches,
                                         std::size_t max_rank = 1);

// ---- templates ---------------------------------------------------------------

enum class TemplateFusion : std::uint8_t {
  norm_weighted,  // mean of the raw descriptors, then L2-normalized (the norm weighs each frame)
  mean,           // mean of the L2-normalized descriptors, then L2-normalized
};
const char* template_fusion_name(TemplateFusion fusion) noexcept;
// One unit-length template from a probe's frame descriptors (all the same
// length, at least one). Throws InvalidArgument on none, mixed lengths, a
// non-finite value, or (mean fusion) an all-zero descriptor.
std::vector<float> make_template(std::span<const std::vector<float>> descriptors,
                                 TemplateFusion fusion);
// Cosine similarity in [−1, 1]; a zero vector gives 0.
double cosine_similarity(std::span<const float> a, std::span<const float> b);

// ---- bootstrap confidence intervals --------------------------------------------

struct Interval {
  double value = std::numeric_limits<double>::quiet_NaN();  // on the data as given
  double lo = std::numeric_limits<double>::quiet_NaN();
  double hi = std::numeric_limits<double>::quiet_NaN();
  int resamples = 0;  // resamples where the metric was defined (finite)
};

struct BootstrapOptions {
  int resamples = 1000;
  double level = 0.95;  // the interval's coverage, in (0, 1)
  std::uint64_t seed = 1;
};

// A two-level (cluster) bootstrap: identities drawn with replacement, then
// each drawn identity's searches drawn with replacement; the gallery stays as
// it is. unit[i] is search i's identity (mated or not; any integers). The
// percentile interval of the metric over the resamples that define it
// (finite values); the same seed gives the same interval.
using SearchMetric = std::function<double(std::span<const Search>)>;
Interval bootstrap(std::span<const Search> searches, std::span<const int> unit,
                   const SearchMetric& metric, const BootstrapOptions& options);
// The same bootstrap for any statistic of items: unit[i] is item i's
// identity; `statistic` gets the drawn items' indices (repeats included).
using IndexStatistic = std::function<double(std::span<const std::size_t>)>;
Interval bootstrap_items(std::span<const int> unit, const IndexStatistic& statistic,
                         const BootstrapOptions& options);

}  // namespace vkjr2::jr2
