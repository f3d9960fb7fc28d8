// The restoration gate (jr2/gate.hpp): its label and re-weighting against
// the formulas, the sharpness feature, heads that learn a known relation,
// the threshold choice on a constructed validation split, and the file.
#include <vkjr2/jr2/gate.hpp>
#include <vkjr2/nets/safetensors.hpp>

#include <gtest/gtest.h>

#include <cmath>
#include <fstream>
#include <numbers>
#include <random>
#include <string>
#include <vector>

#include "support/expect_error.hpp"
#include "support/temp_dir.hpp"
#include "support/test_device.hpp"

namespace vkjr2::jr2 {
namespace {

const double kInvE = std::exp(-1.0);

double density(double x, double mu, double sigma) {
  return std::exp(-(x - mu) * (x - mu) / (2 * sigma * sigma)) /
         (sigma * std::sqrt(2 * std::numbers::pi));
}

TEST(Gate, RankLabelAndReweightingFollowThePaper) {
  EXPECT_NEAR(rank_change_label(1, 1), kInvE, 1e-15);
  EXPECT_NEAR(rank_change_label(7, 7), kInvE, 1e-15);
  EXPECT_NEAR(rank_change_label(4, 1), std::exp(0.75 - 1), 1e-15);  // better: above 1/e
  EXPECT_NEAR(rank_change_label(1, 3), std::exp(-3.0), 1e-15);      // worse: below
  EXPECT_GT(rank_change_label(100, 1), 0.99 * std::exp(-0.0));
  test::expect_invalid_argument([] { rank_change_label(0, 1); }, "ranks 0 and 1");
  for (double m : {-kInvE, -0.25, 0.0, 0.24, 1 - kInvE}) {
    const double f =
        -1.25 + density(m, -0.25, 0.2) + density(m, -kInvE, 0.18) + density(m, 1 - kInvE, 0.3);
    EXPECT_NEAR(rank_label_reweighting(m), f, 1e-12) << m;
  }
  // Worse ranks weigh most; a rank 2 made rank 1 gets a negative f, which
  // the trainer floors.
  EXPECT_GT(rank_label_reweighting(-0.25), 2.0);
  EXPECT_LT(rank_label_reweighting(rank_change_label(2, 1) - kInvE), 0.0);
}

TEST(Gate, SharpnessFallsWithBlurAndIgnoresContrast) {
  const int h = 32, w = 40;
  std::mt19937 rng(3);
  std::uniform_real_distribution<float> u(0.f, 1.f);
  std::vector<float> sharp(std::size_t(h) * w), blurred(sharp.size()), brighter(sharp.size());
  for (float& v : sharp) v = u(rng);
  for (int y = 0; y < h; ++y) {
    for (int x = 0; x < w; ++x) {
      float s = 0;
      int n = 0;
      for (int dy = -2; dy <= 2; ++dy) {
        for (int dx = -2; dx <= 2; ++dx) {
          const int yy = std::clamp(y + dy, 0, h - 1), xx = std::clamp(x + dx, 0, w - 1);
          s += sharp[std::size_t(yy) * w + xx];
          ++n;
        }
      }
      blurred[std::size_t(y) * w + x] = s / float(n);
    }
  }
  for (std::size_t i = 0; i < sharp.size(); ++i) brighter[i] = 3.f * sharp[i] + 10.f;
  const double s0 = gate_sharpness(sharp, h, w, 0, 0, w, h);
  EXPECT_GT(s0, gate_sharpness(blurred, h, w, 0, 0, w, h) + 1.0);
  EXPECT_NEAR(gate_sharpness(brighter, h, w, 0, 0, w, h), s0, 1e-4);
  // The box is clipped to the image; one that misses it is an error.
  EXPECT_NEAR(gate_sharpness(sharp, h, w, -10, -10, w + 10, h + 10), s0, 1e-12);
  test::expect_invalid_argument([&] { gate_sharpness(sharp, h, w, w + 1, 0, w + 9, h); },
                                "smaller than 3×3");
  test::expect_invalid_argument([&] { gate_sharpness(sharp, h + 1, w, 0, 0, w, h); }, "33×40");
}

// Synthetic probes: the quality falls with D/r0; restoring helps (rank 3 →
// 1) exactly the probes whose D/r0 is above 4 and hurts (1 → 2) the others.
std::vector<GateSample> synthetic(int n, std::uint32_t seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> log_d(0.0, std::log(8.0)), noise(-0.02, 0.02);
  std::normal_distribution<float> g(0.f, 1.f);
  std::vector<GateSample> out;
  for (int i = 0; i < n; ++i) {
    GateSample s;
    s.file = "probe" + std::to_string(i);
    s.features.acquired = true;
    s.features.d_over_r0 = std::exp(log_d(rng));
    s.features.descriptor.resize(128);
    double norm = 0;
    for (float& v : s.features.descriptor) {
      v = g(rng);
      norm += double(v) * v;
    }
    for (float& v : s.features.descriptor) v = float(v / std::sqrt(norm));
    s.features.descriptor_norm = 1.0 + noise(rng);
    s.features.detector_score = 0.8 + noise(rng);
    s.features.tracked_share = 1.0;
    s.features.sharpness = -2 - 0.3 * s.features.d_over_r0 + noise(rng);
    s.strength = s.features.d_over_r0 > 4 ? "strong" : "weak";
    s.quality = 0.95 - 0.08 * s.features.d_over_r0;
    s.mated = i % 3 != 0;
    if (s.mated) {
      const bool helps = s.features.d_over_r0 > 4;
      s.rank_raw = helps ? 3 : 1;
      s.rank_post = helps ? 1 : 2;
    }
    out.push_back(s);
  }
  return out;
}

TEST(Gate, HeadsLearnAKnownRelationAndTheThresholdFollowsIt) {
  Device& dev = test::device();
  const std::vector<GateSample> train = synthetic(96, 1), val = synthetic(48, 2);
  {
    GateTrainOptions o;
    o.steps = 800;
    Gate gate = Gate::train(dev, train, o);
    Stream stream(dev);
    std::vector<GateFeatures> f;
    for (const auto& s : val) f.push_back(s.features);
    const std::vector<GatePrediction> p = gate.predict(stream, f);
    double q_err = 0;
    int rank_right = 0, mated = 0;
    for (std::size_t i = 0; i < val.size(); ++i) {
      q_err += std::abs(p[i].quality - val[i].quality) / double(val.size());
      if (!val[i].mated) continue;
      ++mated;
      const double label = rank_change_label(val[i].rank_raw, val[i].rank_post);
      rank_right += (p[i].rank_label >= kInvE) == (label >= kInvE) ? 1 : 0;
    }
    // Held-out probes: the quality within a few hundredths on average, the
    // rank change's sign right for nearly all (those near D/r0 = 4 may miss).
    EXPECT_LT(q_err, 0.04);
    EXPECT_GE(rank_right * 10, mated * 9);

    const GateOutcome o2 = gate.choose_thresholds(stream, val);
    // The gated choice is as good as the best of never and always, and
    // restores about the strong half only.
    EXPECT_GE(o2.mrr_gated, std::max(o2.mrr_degraded, o2.mrr_restored) - 1e-12);
    EXPECT_GT(o2.mrr_gated, o2.mrr_degraded + 0.1);
    std::size_t strong = 0;
    for (const auto& s : val) strong += s.strength == "strong" ? 1 : 0;
    EXPECT_LE(o2.restored, strong + 4);
    EXPECT_GE(o2.restored, strong > 4 ? strong - 4 : 0);
    const GateOutcome again = gate.outcome(stream, val);
    EXPECT_EQ(again.restored, o2.restored);
    EXPECT_EQ(again.mrr_gated, o2.mrr_gated);
  }
}

TEST(Gate, AProbeWithoutATemplateIsRestored) {
  EXPECT_TRUE(Gate::decide(false, 1.0, 0.0, -1.0, 0.0));
  EXPECT_FALSE(Gate::decide(true, 0.5, 0.9, 0.4, 0.0));  // quality above the threshold
  EXPECT_TRUE(Gate::decide(true, 0.3, 0.9, 0.4, 0.0));
  EXPECT_FALSE(Gate::decide(true, 0.3, 0.2, 0.4, 0.1));  // predicted to get worse
  EXPECT_TRUE(Gate::decide(true, 0.3, 0.2, 0.4, 0.2));   // within the margin
}

TEST(Gate, SavesAndLoadsAndRefusesBadFiles) {
  Device& dev = test::device();
  test::TempDir tmp("gate");
  GateTrainOptions o;
  o.steps = 50;
  o.descriptor = true;  // the 133-feature file
  Gate gate = Gate::train(dev, synthetic(24, 5), o);
  gate.set_thresholds(0.6, 0.05);
  gate.set_align(AlignMode::face_api);
  gate.metadata["restorer"] = "r.safetensors";
  const auto path = tmp.path / "gate.safetensors";
  gate.save(path);
  const Gate back = Gate::load(dev, path);
  EXPECT_EQ(back.quality_threshold(), 0.6);
  EXPECT_EQ(back.rank_margin(), 0.05);
  EXPECT_EQ(back.align(), AlignMode::face_api);
  EXPECT_EQ(back.metadata.at("restorer"), "r.safetensors");
  Stream stream(dev);
  const auto val = synthetic(6, 9);
  std::vector<GateFeatures> f;
  for (const auto& s : val) f.push_back(s.features);
  const auto a = gate.predict(stream, f), b = back.predict(stream, f);
  for (std::size_t i = 0; i < a.size(); ++i) {
    EXPECT_EQ(a[i].quality, b[i].quality);
    EXPECT_EQ(a[i].rank_label, b[i].rank_label);
    EXPECT_EQ(a[i].restore, b[i].restore);
  }
  // A file of another kind, and one missing a head's tensor.
  const auto other = tmp.path / "other.safetensors";
  nets::write_safetensors_f32(other, {{"x", HostTensor{{1}, {1.f}}}}, {{"kind", "x"}});
  try {
    (void)Gate::load(dev, other);
    ADD_FAILURE() << "loaded a file that is not a gate";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("is not a gate"), std::string::npos) << e.what();
  }
  nets::SafetensorsFile file = nets::read_safetensors(path);
  std::vector<nets::SafetensorsRecord> kept;
  for (const auto& r : file.tensors) {
    if (r.name != "rank.fc2.weight") kept.push_back(r);
  }
  const auto partial = tmp.path / "partial.safetensors";
  nets::write_safetensors(partial, kept, file.metadata);
  try {
    (void)Gate::load(dev, partial);
    ADD_FAILURE() << "loaded a gate without its rank head";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("rank.fc2.weight"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find(partial.string()), std::string::npos) << e.what();
  }
  // Too few labelled probes, and features that are not finite.
  test::expect_invalid_argument([&] { (void)Gate::train(dev, synthetic(4, 1), o); }, "at least 3");
  auto bad = synthetic(12, 1);
  bad[2].features.sharpness = std::nan("");
  test::expect_invalid_argument([&] { (void)Gate::train(dev, bad, o); }, "sharpness");
}

}  // namespace
}  // namespace vkjr2::jr2
