#include <vkjr2/jr2/metrics.hpp>
#include <vkjr2/runtime/error.hpp>

#include <algorithm>
#include <cmath>
#include <map>
#include <random>
#include <string>

#include "internal/text_and_draws.hpp"

namespace vkjr2::jr2 {
namespace {

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

void check_rate(double rate, const char* op, const char* name) {
  if (!(rate > 0.0 && rate < 1.0)) {
    throw InvalidArgument(op,
                          std::string(name) + " = " + std::to_string(rate) + " is not in (0, 1)",
                          "pass a rate such as 0.01 for 1 %");
  }
}

// The operating point at target rate p over the negative scores (impostor
// scores, or the best scores of non-mated searches): t is the k-th largest,
// k = max(1, ⌊p·N⌋). Leaves `value` to the caller.
OperatingPoint operating_point(std::vector<double> negatives, double target) {
  OperatingPoint op;
  op.target = target;
  op.negatives = negatives.size();
  op.value = kNaN;
  op.achieved = kNaN;
  op.threshold = kNaN;
  if (negatives.empty()) return op;
  const auto n = double(negatives.size());
  op.reported = n >= std::ceil(1.0 / target - 1e-9);
  const std::size_t k =
      std::max<std::size_t>(1, std::size_t(std::floor(target * n + 1e-9 * target * n)));
  std::nth_element(negatives.begin(), negatives.begin() + std::ptrdiff_t(k - 1), negatives.end(),
                   std::greater<>());
  op.threshold = negatives[k - 1];
  const auto above =
      std::count_if(negatives.begin(), negatives.end(), [&](double s) { return s > op.threshold; });
  op.achieved = double(above) / n;
  return op;
}

double best_score(const Search& s) { return *std::max_element(s.scores.begin(), s.scores.end()); }

// numpy's default (linear) quantile of sorted values.
double quantile(const std::vector<double>& sorted, double q) {
  const double pos = q * double(sorted.size() - 1);
  const auto lo = std::size_t(std::floor(pos));
  const std::size_t hi = std::min(lo + 1, sorted.size() - 1);
  return sorted[lo] + (pos - double(lo)) * (sorted[hi] - sorted[lo]);
}

}  // namespace

void check_searches(std::span<const Search> searches, const char* what) {
  if (searches.empty()) return;
  const std::size_t gallery = searches.front().scores.size();
  for (std::size_t i = 0; i < searches.size(); ++i) {
    const Search& s = searches[i];
    const std::string where = std::string(what) + ": search " + std::to_string(i);
    if (s.scores.empty()) {
      throw InvalidArgument("check_searches", where + " has no scores",
                            "enroll at least one gallery identity");
    }
    if (s.scores.size() != gallery) {
      throw InvalidArgument("check_searches",
                            where + " has " + std::to_string(s.scores.size()) +
                                " scores, search 0 has " + std::to_string(gallery),
                            "score every probe against the same gallery");
    }
    if (s.mate >= int(s.scores.size()) || s.mate < -1) {
      throw InvalidArgument("check_searches",
                            where + " names mate " + std::to_string(s.mate) + " of a gallery of " +
                                std::to_string(gallery),
                            "mate is a gallery index, or -1 for a non-mated search");
    }
    for (double v : s.scores) {
      if (!std::isfinite(v)) {
        throw InvalidArgument("check_searches", where + " has a non-finite score",
                              "check the descriptors it was computed from (NaN input?)");
      }
    }
  }
}

VerificationScores verification_scores(std::span<const Search> searches) {
  VerificationScores v;
  for (const Search& s : searches) {
    for (std::size_t i = 0; i < s.scores.size(); ++i) {
      if (int(i) == s.mate) {
        v.genuine.push_back(s.scores[i]);
      } else {
        v.impostor.push_back(s.scores[i]);
      }
    }
  }
  return v;
}

std::vector<RocPoint> roc_curve(std::span<const double> genuine, std::span<const double> impostor) {
  if (genuine.empty() || impostor.empty()) {
    throw InvalidArgument("roc_curve",
                          std::to_string(genuine.size()) + " genuine and " +
                              std::to_string(impostor.size()) + " impostor scores",
                          "a ROC needs at least one of each (mated and non-mated pairs)");
  }
  struct Scored {
    double score;
    bool genuine;
  };
  std::vector<Scored> all;
  all.reserve(genuine.size() + impostor.size());
  for (double s : genuine) all.push_back({s, true});
  for (double s : impostor) all.push_back({s, false});
  std::sort(all.begin(), all.end(),
            [](const Scored& a, const Scored& b) { return a.score > b.score; });
  std::vector<RocPoint> roc;
  roc.push_back({std::numeric_limits<double>::infinity(), 0.0, 0.0});
  std::size_t tp = 0, fp = 0;
  for (std::size_t i = 0; i < all.size(); ++i) {
    (all[i].genuine ? tp : fp) += 1;
    if (i + 1 < all.size() && all[i + 1].score == all[i].score)
      continue;  // NOLINT(clang-diagnostic-float-equal)
    roc.push_back(
        {all[i].score, double(fp) / double(impostor.size()), double(tp) / double(genuine.size())});
  }
  return roc;
}

OperatingPoint tar_at_far(std::span<const double> genuine, std::span<const double> impostor,
                          double far) {
  check_rate(far, "tar_at_far", "far");
  OperatingPoint op = operating_point({impostor.begin(), impostor.end()}, far);
  if (op.negatives == 0 || genuine.empty()) {
    op.reported = false;
    return op;
  }
  const auto accepted =
      std::count_if(genuine.begin(), genuine.end(), [&](double s) { return s > op.threshold; });
  op.value = double(accepted) / double(genuine.size());
  return op;
}

std::size_t mate_rank(const Search& search) {
  if (!search.mated()) return 0;
  const double mate = search.scores[std::size_t(search.mate)];
  std::size_t rank = 1;
  for (std::size_t i = 0; i < search.scores.size(); ++i) {
    if (int(i) != search.mate && search.scores[i] >= mate) ++rank;
  }
  return rank;
}

std::vector<double> cmc(std::span<const Search> searches, std::size_t max_rank) {
  std::vector<std::size_t> hits(max_rank, 0);
  std::size_t mated = 0;
  for (const Search& s : searches) {
    if (!s.mated()) continue;
    ++mated;
    const std::size_t r = mate_rank(s);
    if (r <= max_rank) ++hits[r - 1];
  }
  std::vector<double> curve(max_rank, kNaN);
  if (mated == 0) return curve;
  std::size_t cumulative = 0;
  for (std::size_t k = 0; k < max_rank; ++k) {
    cumulative += hits[k];
    curve[k] = double(cumulative) / double(mated);
  }
  return curve;
}

double fpir(std::span<const Search> searches, double threshold) {
  std::size_t n = 0, alarms = 0;
  for (const Search& s : searches) {
    if (s.mated()) continue;
    ++n;
    if (best_score(s) > threshold) ++alarms;
  }
  return n == 0 ? kNaN : double(alarms) / double(n);
}

double fnir(std::span<const Search> searches, double threshold, std::size_t max_rank) {
  std::size_t n = 0, misses = 0;
  for (const Search& s : searches) {
    if (!s.mated()) continue;
    ++n;
    if (mate_rank(s) > max_rank || !(s.scores[std::size_t(s.mate)] > threshold)) ++misses;
  }
  return n == 0 ? kNaN : double(misses) / double(n);
}

OperatingPoint fnir_at_fpir(std::span<const Search> searches, double fpir_target,
                            std::size_t max_rank) {
  check_rate(fpir_target, "fnir_at_fpir", "fpir");
  std::vector<double> best;
  bool any_mated = false;
  for (const Search& s : searches) {
    if (s.mated()) {
      any_mated = true;
    } else {
      best.push_back(best_score(s));
    }
  }
  OperatingPoint op = operating_point(std::move(best), fpir_target);
  if (op.negatives == 0 || !any_mated) {
    op.reported = false;
    return op;
  }
  op.value = fnir(searches, op.threshold, max_rank);
  return op;
}

std::vector<OpenSetPoint> open_set_curve(std::span<const Search> searches, std::size_t max_rank) {
  std::vector<double> thresholds;
  for (const Search& s : searches) {
    if (!s.mated()) thresholds.push_back(best_score(s));
  }
  std::sort(thresholds.begin(), thresholds.end(), std::greater<>());
  thresholds.erase(std::unique(thresholds.begin(), thresholds.end()), thresholds.end());
  thresholds.push_back(-std::numeric_limits<double>::infinity());
  std::vector<OpenSetPoint> curve;
  curve.reserve(thresholds.size());
  for (double t : thresholds) curve.push_back({t, fpir(searches, t), fnir(searches, t, max_rank)});
  return curve;
}

const char* template_fusion_name(TemplateFusion fusion) noexcept {
  return fusion == TemplateFusion::mean ? "mean" : "norm_weighted";
}

std::vector<float> make_template(std::span<const std::vector<float>> descriptors,
                                 TemplateFusion fusion) {
  if (descriptors.empty()) {
    throw InvalidArgument("make_template", "no descriptors (the probe had no usable frame)",
                          "leave the probe out, or count it as a failure to enrol");
  }
  const std::size_t d = descriptors.front().size();
  std::vector<double> sum(d, 0.0);
  for (std::size_t f = 0; f < descriptors.size(); ++f) {
    const std::vector<float>& v = descriptors[f];
    if (v.size() != d || d == 0) {
      throw InvalidArgument("make_template",
                            "descriptor " + std::to_string(f) + " has " + std::to_string(v.size()) +
                                " values, descriptor 0 has " + std::to_string(d),
                            "pass descriptors of one network");
    }
    double norm = 0;
    for (float x : v) {
      if (!std::isfinite(x)) {
        throw InvalidArgument("make_template",
                              "descriptor " + std::to_string(f) + " has a non-finite value",
                              "check the frame it came from");
      }
      norm += double(x) * double(x);
    }
    norm = std::sqrt(norm);
    double weight = 1.0;
    if (fusion == TemplateFusion::mean) {
      if (norm == 0) {  // NOLINT(clang-diagnostic-float-equal)
        throw InvalidArgument("make_template", "descriptor " + std::to_string(f) + " is all zeros",
                              "use norm_weighted fusion, or drop the frame");
      }
      weight = 1.0 / norm;
    }
    for (std::size_t i = 0; i < d; ++i) sum[i] += weight * double(v[i]);
  }
  double norm = 0;
  for (double x : sum) norm += x * x;
  norm = std::sqrt(norm);
  std::vector<float> t(d, 0.f);
  if (norm > 0) {
    for (std::size_t i = 0; i < d; ++i) t[i] = float(sum[i] / norm);
  }
  return t;
}

double cosine_similarity(std::span<const float> a, std::span<const float> b) {
  if (a.size() != b.size()) {
    throw InvalidArgument(
        "cosine_similarity",
        "vectors of " + std::to_string(a.size()) + " and " + std::to_string(b.size()) + " values",
        "compare descriptors of one network");
  }
  double ab = 0, aa = 0, bb = 0;
  for (std::size_t i = 0; i < a.size(); ++i) {
    ab += double(a[i]) * double(b[i]);
    aa += double(a[i]) * double(a[i]);
    bb += double(b[i]) * double(b[i]);
  }
  return aa > 0 && bb > 0 ? ab / std::sqrt(aa * bb) : 0.0;
}

Interval bootstrap_items(std::span<const int> unit, const IndexStatistic& statistic,
                         const BootstrapOptions& options) {
  if (options.resamples < 1 || !(options.level > 0 && options.level < 1)) {
    throw InvalidArgument("bootstrap",
                          "resamples = " + std::to_string(options.resamples) +
                              ", level = " + std::to_string(options.level),
                          "use resamples ≥ 1 (1000 is usual) and a level in (0, 1)");
  }
  Interval iv;
  std::vector<std::size_t> all(unit.size());
  for (std::size_t i = 0; i < all.size(); ++i) all[i] = i;
  iv.value = statistic(all);
  if (unit.empty()) return iv;
  // Each identity's items, in a fixed order (by identity, then position).
  std::map<int, std::vector<std::size_t>> by_unit;
  for (std::size_t i = 0; i < unit.size(); ++i) by_unit[unit[i]].push_back(i);
  std::vector<const std::vector<std::size_t>*> groups;
  groups.reserve(by_unit.size());
  for (const auto& [id, members] : by_unit) groups.push_back(&members);

  std::mt19937_64 rng(options.seed);
  std::vector<double> values;
  values.reserve(std::size_t(options.resamples));
  std::vector<std::size_t> sample;
  sample.reserve(unit.size());
  for (int b = 0; b < options.resamples; ++b) {
    sample.clear();
    for (std::size_t g = 0; g < groups.size(); ++g) {
      const std::vector<std::size_t>& members = *groups[detail::draw_below(rng, groups.size())];
      for (std::size_t m = 0; m < members.size(); ++m) {
        sample.push_back(members[detail::draw_below(rng, members.size())]);
      }
    }
    const double v = statistic(sample);
    if (std::isfinite(v)) values.push_back(v);
  }
  iv.resamples = int(values.size());
  if (values.empty()) return iv;
  std::sort(values.begin(), values.end());
  const double tail = (1.0 - options.level) / 2.0;
  iv.lo = quantile(values, tail);
  iv.hi = quantile(values, 1.0 - tail);
  return iv;
}

Interval bootstrap(std::span<const Search> searches, std::span<const int> unit,
                   const SearchMetric& metric, const BootstrapOptions& options) {
  if (unit.size() != searches.size()) {
    throw InvalidArgument("bootstrap",
                          std::to_string(unit.size()) + " identities for " +
                              std::to_string(searches.size()) + " searches",
                          "give every search its identity");
  }
  std::vector<Search> sample;
  return bootstrap_items(
      unit,
      [&](std::span<const std::size_t> drawn) {
        sample.clear();
        for (std::size_t i : drawn) sample.push_back(searches[i]);
        return metric(sample);
      },
      options);
}

}  // namespace vkjr2::jr2
