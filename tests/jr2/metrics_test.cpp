// The recognition metrics: hand-worked cases (ties included), agreement with
// scikit-learn's roc_curve and with the CMC and FNIR/FPIR definitions written
// in numpy (tests/jr2/metrics_reference.py) on random score sets to 1e-9, the
// templates, and the bootstrap's intervals.
#include <vkjr2/jr2/metrics.hpp>
#include <vkjr2/runtime/error.hpp>

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <random>

namespace vkjr2::jr2 {
namespace {

namespace fs = std::filesystem;
using nlohmann::json;

// Five searches against a gallery of three identities, worked by hand in the
// comments below (and in docs/eval.md).
std::vector<Search> worked_example() {
  return {
      {{0.9, 0.3, 0.5}, 0},    // mate 0.9, rank 1
      {{0.4, 0.8, 0.8}, 1},    // mate 0.8 ties a non-mate: rank 2
      {{0.2, 0.1, 0.6}, 2},    // mate 0.6, rank 1
      {{0.7, 0.35, 0.1}, -1},  // non-mated, best 0.7
      {{0.3, 0.2, 0.45}, -1},  // non-mated, best 0.45
  };
}

TEST(Metrics, VerificationScoresSplitMateFromNonMate) {
  const auto v = verification_scores(worked_example());
  EXPECT_EQ(v.genuine, (std::vector<double>{0.9, 0.8, 0.6}));
  EXPECT_EQ(v.impostor.size(), 12u);
}

TEST(Metrics, RocWorkedExample) {
  const auto v = verification_scores(worked_example());
  const auto roc = roc_curve(v.genuine, v.impostor);
  // 11 distinct scores, after the (+inf, 0, 0) start.
  ASSERT_EQ(roc.size(), 12u);
  EXPECT_TRUE(std::isinf(roc[0].threshold));
  EXPECT_DOUBLE_EQ(roc[1].threshold, 0.9);
  EXPECT_DOUBLE_EQ(roc[1].tar, 1.0 / 3);
  EXPECT_DOUBLE_EQ(roc[1].far, 0.0);
  EXPECT_DOUBLE_EQ(roc[2].threshold, 0.8);  // a genuine and an impostor tie
  EXPECT_DOUBLE_EQ(roc[2].tar, 2.0 / 3);
  EXPECT_DOUBLE_EQ(roc[2].far, 1.0 / 12);
  EXPECT_DOUBLE_EQ(roc[4].threshold, 0.6);
  EXPECT_DOUBLE_EQ(roc[4].tar, 1.0);
  EXPECT_DOUBLE_EQ(roc[4].far, 2.0 / 12);
  EXPECT_DOUBLE_EQ(roc.back().far, 1.0);
  EXPECT_DOUBLE_EQ(roc.back().tar, 1.0);
}

TEST(Metrics, TarAtFarWorkedExample) {
  const auto v = verification_scores(worked_example());
  // FAR 0.1 of 12 impostors: k = 1, t = 0.8; only 0.9 > t (the genuine 0.8
  // ties t and is rejected).
  OperatingPoint p = tar_at_far(v.genuine, v.impostor, 0.1);
  EXPECT_TRUE(p.reported);
  EXPECT_DOUBLE_EQ(p.threshold, 0.8);
  EXPECT_DOUBLE_EQ(p.value, 1.0 / 3);
  EXPECT_DOUBLE_EQ(p.achieved, 0.0);
  EXPECT_EQ(p.negatives, 12u);
  // FAR 0.25: k = 3, impostors 0.8, 0.7, 0.5, … so t = 0.5; all genuine pass.
  p = tar_at_far(v.genuine, v.impostor, 0.25);
  EXPECT_DOUBLE_EQ(p.threshold, 0.5);
  EXPECT_DOUBLE_EQ(p.value, 1.0);
  EXPECT_DOUBLE_EQ(p.achieved, 2.0 / 12);
  // FAR 0.01 needs 100 impostors: computed, not reported.
  p = tar_at_far(v.genuine, v.impostor, 0.01);
  EXPECT_FALSE(p.reported);
  EXPECT_DOUBLE_EQ(p.value, 1.0 / 3);
  EXPECT_THROW(tar_at_far(v.genuine, v.impostor, 0.0), InvalidArgument);
  EXPECT_THROW(tar_at_far(v.genuine, v.impostor, 1.0), InvalidArgument);
  EXPECT_THROW(tar_at_far(v.genuine, v.impostor, std::nan("")), InvalidArgument);
}

TEST(Metrics, RanksAndCmcWorkedExample) {
  const auto s = worked_example();
  EXPECT_EQ(mate_rank(s[0]), 1u);
  EXPECT_EQ(mate_rank(s[1]), 2u);  // a tie ranks the mate below
  EXPECT_EQ(mate_rank(s[2]), 1u);
  EXPECT_EQ(mate_rank(s[3]), 0u);
  const auto c = cmc(s, 3);
  ASSERT_EQ(c.size(), 3u);
  EXPECT_DOUBLE_EQ(c[0], 2.0 / 3);
  EXPECT_DOUBLE_EQ(c[1], 1.0);
  EXPECT_DOUBLE_EQ(c[2], 1.0);
  const std::vector<Search> none = {s[3], s[4]};
  EXPECT_TRUE(std::isnan(cmc(none, 1)[0]));
}

TEST(Metrics, OpenSetWorkedExample) {
  const auto s = worked_example();
  // Non-mated best scores 0.7 and 0.45.
  EXPECT_DOUBLE_EQ(fpir(s, 0.5), 0.5);
  EXPECT_DOUBLE_EQ(fpir(s, 0.7), 0.0);  // not above the threshold
  // FPIR 0.5 of 2: k = 1, t = 0.7. Rank 1: search 0 hits (0.9 > 0.7), search
  // 1 misses (rank 2), search 2 misses (0.6 ≤ 0.7).
  OperatingPoint p = fnir_at_fpir(s, 0.5, 1);
  EXPECT_TRUE(p.reported);
  EXPECT_DOUBLE_EQ(p.threshold, 0.7);
  EXPECT_DOUBLE_EQ(p.value, 2.0 / 3);
  EXPECT_DOUBLE_EQ(p.achieved, 0.0);
  // Within rank 2, search 1 hits too (0.8 > 0.7).
  EXPECT_DOUBLE_EQ(fnir_at_fpir(s, 0.5, 2).value, 1.0 / 3);
  EXPECT_FALSE(fnir_at_fpir(s, 0.1, 1).reported);  // 2 non-mated searches cannot measure 10 %
  const auto curve = open_set_curve(s, 1);
  ASSERT_EQ(curve.size(), 3u);  // 0.7, 0.45, −inf
  EXPECT_DOUBLE_EQ(curve[0].fpir, 0.0);
  EXPECT_DOUBLE_EQ(curve[1].fpir, 0.5);
  EXPECT_DOUBLE_EQ(curve[1].fnir, 1.0 / 3);
  EXPECT_DOUBLE_EQ(curve[2].fpir, 1.0);
}

TEST(Metrics, CheckSearchesNamesTheFault) {
  std::vector<Search> s = worked_example();
  EXPECT_NO_THROW(check_searches(s, "scores.csv"));
  s[2].mate = 3;
  try {
    check_searches(s, "scores.csv");
    FAIL() << "a mate outside the gallery was accepted";
  } catch (const InvalidArgument& e) {
    EXPECT_NE(std::string(e.what()).find("scores.csv: search 2"), std::string::npos) << e.what();
  }
  s = worked_example();
  s[1].scores.pop_back();
  EXPECT_THROW(check_searches(s, "x"), InvalidArgument);
  s = worked_example();
  s[4].scores[0] = std::nan("");
  EXPECT_THROW(check_searches(s, "x"), InvalidArgument);
}

// Random score sets (some on a coarse grid, so that ties are common) against
// scikit-learn and numpy.
std::vector<Search> random_searches(std::mt19937_64& rng, bool ties) {
  std::uniform_int_distribution<int> gallery_size(2, 30), count(20, 300);
  const int g = gallery_size(rng), n = count(rng);
  std::normal_distribution<double> noise(0.0, 1.0);
  std::bernoulli_distribution mated(0.7);
  std::vector<Search> out(std::size_t(n), Search{});
  for (Search& s : out) {
    s.mate = mated(rng) ? std::uniform_int_distribution<int>(0, g - 1)(rng) : -1;
    for (int i = 0; i < g; ++i) {
      double v = noise(rng) + (i == s.mate ? 1.5 : 0.0);
      if (ties) v = std::round(v * 4) / 4;
      s.scores.push_back(v);
    }
  }
  return out;
}

json to_json(const std::vector<Search>& searches, const std::vector<double>& fars,
             const std::vector<double>& fpirs, std::size_t max_rank, std::size_t cmc_ranks) {
  json c;
  c["searches"] = json::array();
  for (const Search& s : searches)
    c["searches"].push_back({{"scores", s.scores}, {"mate", s.mate}});
  c["fars"] = fars;
  c["fpirs"] = fpirs;
  c["max_rank"] = max_rank;
  c["cmc_ranks"] = cmc_ranks;
  return c;
}

TEST(Metrics, AgreesWithScikitLearn) {
  const std::uint64_t seed = 20261206;
  std::mt19937_64 rng(seed);
  const std::vector<double> fars = {0.3, 0.1, 0.01, 0.001};
  const std::vector<double> fpirs = {0.5, 0.1, 0.01};
  struct Case {
    std::vector<Search> searches;
    std::size_t max_rank;
  };
  std::vector<Case> cases;
  json in = json::array();
  for (int i = 0; i < 12; ++i) {
    Case c{random_searches(rng, i % 2 == 1), std::size_t(1 + (i % 3))};
    // The definitions need mated and non-mated searches.
    c.searches.push_back({std::vector<double>(c.searches[0].scores.size(), 0.25), 0});
    c.searches.push_back({std::vector<double>(c.searches[0].scores.size(), 0.5), -1});
    in.push_back(to_json(c.searches, fars, fpirs, c.max_rank, 5));
    cases.push_back(std::move(c));
  }
  const fs::path dir =
      fs::temp_directory_path() /
      ("vkjr2_metrics_" + std::to_string(::testing::UnitTest::GetInstance()->random_seed()) + "_" +
       std::to_string(std::random_device{}()));
  fs::create_directories(dir);
  std::ofstream(dir / "in.json") << in.dump();
  const std::string cmd = std::string(VKJR2_PYTHON3) + " " + VKJR2_METRICS_REFERENCE + " " +
                          (dir / "in.json").string() + " " + (dir / "out.json").string();
  ASSERT_EQ(std::system(cmd.c_str()), 0)  // NOLINT(concurrency-mt-unsafe)
      << cmd << " failed: it needs python3-sklearn and python3-numpy (scripts/setup installs them)";
  json out;
  std::ifstream(dir / "out.json") >> out;
  fs::remove_all(dir);
  ASSERT_EQ(out.size(), cases.size());

  constexpr double kTol = 1e-9;
  for (std::size_t ci = 0; ci < cases.size(); ++ci) {
    SCOPED_TRACE("case " + std::to_string(ci) + " (seed " + std::to_string(seed) + ")");
    const Case& c = cases[ci];
    const json& ref = out[ci];
    const auto v = verification_scores(c.searches);
    const auto roc = roc_curve(v.genuine, v.impostor);
    ASSERT_EQ(roc.size(), ref["roc_far"].size());
    for (std::size_t i = 0; i < roc.size(); ++i) {
      EXPECT_NEAR(roc[i].far, ref["roc_far"][i].get<double>(), kTol) << i;
      EXPECT_NEAR(roc[i].tar, ref["roc_tar"][i].get<double>(), kTol) << i;
      // scikit-learn 1.2 starts at max + 1 rather than +inf: compare from 1.
      if (i > 0) {
        EXPECT_NEAR(roc[i].threshold, ref["roc_threshold"][i].get<double>(), kTol) << i;
      }
    }
    for (std::size_t f = 0; f < fars.size(); ++f) {
      EXPECT_NEAR(tar_at_far(v.genuine, v.impostor, fars[f]).value, ref["tar"][f].get<double>(),
                  kTol)
          << "FAR " << fars[f];
    }
    const auto curve = cmc(c.searches, 5);
    for (std::size_t k = 0; k < curve.size(); ++k) {
      EXPECT_NEAR(curve[k], ref["cmc"][k].get<double>(), kTol) << "rank " << k + 1;
    }
    for (std::size_t f = 0; f < fpirs.size(); ++f) {
      EXPECT_NEAR(fnir_at_fpir(c.searches, fpirs[f], c.max_rank).value,
                  ref["fnir"][f].get<double>(), kTol)
          << "FPIR " << fpirs[f] << ", R " << c.max_rank;
    }
  }
}

TEST(Metrics, Templates) {
  const std::vector<std::vector<float>> d = {{3.f, 4.f}, {0.f, 1.f}};
  // norm-weighted: (3, 5)/√34.
  auto t = make_template(d, TemplateFusion::norm_weighted);
  EXPECT_NEAR(t[0], 3 / std::sqrt(34.0), 1e-6);
  EXPECT_NEAR(t[1], 5 / std::sqrt(34.0), 1e-6);
  // mean of unit vectors: (0.6, 1.8)/|…|.
  t = make_template(d, TemplateFusion::mean);
  const double n = std::sqrt(0.6 * 0.6 + 1.8 * 1.8);
  EXPECT_NEAR(t[0], 0.6 / n, 1e-6);
  EXPECT_NEAR(t[1], 1.8 / n, 1e-6);
  EXPECT_NEAR(cosine_similarity(t, t), 1.0, 1e-6);
  EXPECT_NEAR(cosine_similarity(std::vector<float>{1, 0}, std::vector<float>{0, 2}), 0.0, 1e-12);
  EXPECT_THROW(make_template({}, TemplateFusion::mean), InvalidArgument);
  const std::vector<std::vector<float>> mixed = {{1.f, 2.f}, {1.f}};
  EXPECT_THROW(make_template(mixed, TemplateFusion::mean), InvalidArgument);
  const std::vector<std::vector<float>> zero = {{0.f, 0.f}};
  EXPECT_THROW(make_template(zero, TemplateFusion::mean), InvalidArgument);
  const std::vector<std::vector<float>> nan = {{std::nanf(""), 0.f}};
  EXPECT_THROW(make_template(nan, TemplateFusion::norm_weighted), InvalidArgument);
}

double rank1(std::span<const Search> s) { return cmc(s, 1)[0]; }

// n identities with `per` identical searches each; the share p of them whose
// mate is at rank 1 is the same for every search of an identity.
std::vector<Search> clustered(int n, int per, double p, std::vector<int>& unit) {
  std::vector<Search> s;
  unit.clear();
  for (int i = 0; i < n; ++i) {
    const bool hit = i < int(std::lround(p * n));
    for (int j = 0; j < per; ++j) {
      s.push_back({{hit ? 1.0 : 0.0, 0.5}, 0});
      unit.push_back(i);
    }
  }
  return s;
}

TEST(Metrics, BootstrapIsSeededAndHasTheBinomialWidth) {
  std::vector<int> unit;
  const auto s = clustered(400, 1, 0.7, unit);
  BootstrapOptions o;
  o.resamples = 2000;
  const Interval a = bootstrap(s, unit, rank1, o);
  const Interval b = bootstrap(s, unit, rank1, o);
  EXPECT_EQ(a.lo, b.lo);
  EXPECT_EQ(a.hi, b.hi);
  EXPECT_DOUBLE_EQ(a.value, 0.7);
  EXPECT_EQ(a.resamples, 2000);
  EXPECT_LT(a.lo, a.value);
  EXPECT_GT(a.hi, a.value);
  // Binomial: 2·1.96·√(p(1−p)/n) = 0.0898. The percentile bounds of 2000
  // resamples scatter by a few per cent of that; 15 % is > 4σ.
  EXPECT_NEAR(a.hi - a.lo, 2 * 1.96 * std::sqrt(0.7 * 0.3 / 400), 0.15 * 0.0898);
  o.seed = 2;
  const Interval c = bootstrap(s, unit, rank1, o);
  EXPECT_TRUE(c.lo != a.lo || c.hi != a.hi);
}

TEST(Metrics, BootstrapResamplesIdentitiesNotOnlySearches) {
  // 40 identities × 10 identical searches: the information is that of 40
  // samples, so the interval is √10 ≈ 3.2 times wider than if the 400
  // searches were independent.
  std::vector<int> unit;
  const auto s = clustered(40, 10, 0.7, unit);
  BootstrapOptions o;
  o.resamples = 2000;
  const Interval clustered_iv = bootstrap(s, unit, rank1, o);
  std::vector<int> independent(unit.size());
  for (std::size_t i = 0; i < independent.size(); ++i) independent[i] = int(i);
  const Interval flat_iv = bootstrap(s, independent, rank1, o);
  const double ratio = (clustered_iv.hi - clustered_iv.lo) / (flat_iv.hi - flat_iv.lo);
  EXPECT_GT(ratio, 2.4);
  EXPECT_LT(ratio, 4.2);
}

TEST(Metrics, BootstrapSkipsUndefinedResamplesAndChecksItsInput) {
  // One mated search among 19 non-mated ones: many resamples have no mated
  // search, where Rank-1 is undefined; they are left out and counted.
  std::vector<Search> s = {{{1.0, 0.0}, 0}};
  std::vector<int> unit = {0};
  for (int i = 1; i < 20; ++i) {
    s.push_back({{0.2, 0.1}, -1});
    unit.push_back(i);
  }
  BootstrapOptions o;
  o.resamples = 500;
  const Interval iv = bootstrap(s, unit, rank1, o);
  EXPECT_LT(iv.resamples, 500);
  EXPECT_GT(iv.resamples, 100);
  EXPECT_DOUBLE_EQ(iv.lo, 1.0);
  const std::vector<int> short_unit = {0};
  EXPECT_THROW(bootstrap(s, short_unit, rank1, o), InvalidArgument);
  o.level = 1.0;
  EXPECT_THROW(bootstrap(s, unit, rank1, o), InvalidArgument);
}

}  // namespace
}  // namespace vkjr2::jr2
