// The P2S network: shapes, a tiny training run that must beat the mean-PSF
// baseline, the one-file artifact (round trip, truncated, wrong shapes, NaN,
// extra tensors) and make_p2s_artifact end to end.
#include <vkjr2/nets/safetensors.hpp>
#include <vkjr2/runtime/error.hpp>
#include <vkjr2/runtime/host_tensor.hpp>
#include <vkjr2/sim/noll.hpp>
#include <vkjr2/sim/p2s.hpp>

#include <gtest/gtest.h>
#include <unistd.h>

#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <limits>
#include <memory>
#include <string>

#include "support/test_device.hpp"

namespace vkjr2::sim {
namespace {

namespace fs = std::filesystem;
std::size_t sz(std::int64_t v) { return static_cast<std::size_t>(v); }

constexpr int kJMax = 21;  // tiny: 18 inputs

PsfBasisConfig tiny_basis_config() {
  PsfBasisConfig c;
  c.size = 15;
  c.count = 12;
  c.samples = 300;
  c.min_pupil_px = 32;
  return c;
}

P2sTrainConfig tiny_train_config() {
  P2sTrainConfig c;
  c.steps = 150;
  c.batch = 64;
  c.train_samples = 1024;
  c.test_samples = 128;
  c.warmup_steps = 10;
  c.lr = 3e-3f;
  c.min_pupil_px = 32;
  return c;
}

class P2s : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    basis_ = std::make_unique<PsfBasis>(
        make_psf_basis(test::device(), 0.61, kJMax, tiny_basis_config()));
    net_ = std::make_unique<P2sNet>(test::device(), p2s_config_for(*basis_));
    report_ =
        train_p2s(test::device(), *net_, *basis_, tiny_train_config(), [](const P2sProgress& p) {
          if (p.stage == "train" && p.done == 1) first_loss_ = p.loss;
        });
    dir_ = fs::temp_directory_path() / ("vkjr2_p2s_test_" + std::to_string(::getpid()));
    fs::create_directories(dir_);
  }
  static void TearDownTestSuite() {
    std::error_code ec;
    fs::remove_all(dir_, ec);
    net_.reset();
    basis_.reset();
  }
  static fs::path saved(const std::string& name) {
    fs::path p = dir_ / name;
    save_p2s_model(p, *basis_, *net_);
    return p;
  }
  // Rewrites a saved model with `edit` applied to its tensors.
  template <class Edit>
  static fs::path edited(const std::string& name, Edit edit) {
    fs::path p = saved(name);
    const nets::SafetensorsFile f = nets::read_safetensors(p);
    std::map<std::string, vkjr2::HostTensor> t;
    for (const auto& r : f.tensors) t[r.name] = r.to_host();
    edit(t);
    nets::write_safetensors_f32(p, t, f.metadata);
    return p;
  }
  static void expect_load_error(const fs::path& p, const std::string& needle) {
    try {
      (void)load_p2s_model(test::device(), p);
      ADD_FAILURE() << "loading " << p << " did not throw";
    } catch (const InvalidArgument& e) {
      const std::string what = e.what();
      EXPECT_NE(what.find(p.string()), std::string::npos) << what;
      EXPECT_NE(what.find(needle), std::string::npos) << what;
    }
  }

  static inline std::unique_ptr<PsfBasis> basis_;
  static inline std::unique_ptr<P2sNet> net_;
  static inline P2sTrainReport report_;
  static inline double first_loss_ = 0;
  static inline fs::path dir_;
};

TEST_F(P2s, ShapesAndInputScale) {
  EXPECT_EQ(net_->inputs(), kJMax - 3);
  EXPECT_EQ(net_->outputs(), 11);
  EXPECT_FLOAT_EQ(net_->config().output_scale, std::sqrt(basis_->variances[1]));
  const std::vector<float> s = net_->input_scale.value().download();
  ASSERT_EQ(s.size(), sz(kJMax - 3));
  // a_4 at D/r0 = 4 has σ = √⟨a4²⟩ · 4^(5/6): scaled to 1.
  EXPECT_NEAR(s[0] * std::sqrt(noll_covariance(4, 4)) * std::pow(4.0, 5.0 / 6.0), 1.0, 1e-6);
  Stream stream(test::device());
  nets::Tape tape(stream, false);
  const nets::Var bad(Tensor::from(test::device(), Shape{2, 5}, std::vector<float>(10, 0.f)));
  EXPECT_THROW((void)net_->forward(tape, bad), InvalidArgument);
  const std::vector<float> b =
      predict_betas(test::device(), *net_, std::vector<double>(sz(3 * 18)));
  ASSERT_EQ(b.size(), sz(3 * 12));
  EXPECT_EQ(b[0], 1.f);
  EXPECT_EQ(b[12], 1.f);
  EXPECT_EQ(b[1], b[13]);  // equal inputs, equal outputs
}

TEST_F(P2s, TrainingBeatsTheMeanPsf) {
  std::printf(
      "tiny P2S (S=15, K=12, M=300, J=%d, 150 steps): loss %.4f → %.4f; held-out rel L2: "
      "P2S %.4f, PCA %.4f, mean PSF %.4f; train-set P2S %.4f; %.2f s (data %.2f, train "
      "%.2f)\n",
      kJMax, first_loss_, report_.final_loss, report_.test_p2s_rel_l2, report_.test_pca_rel_l2,
      report_.test_mean_rel_l2, report_.train_p2s_rel_l2, report_.total_seconds,
      report_.data_seconds, report_.train_seconds);
  EXPECT_EQ(report_.steps, 150);
  EXPECT_LT(report_.final_loss, 0.5 * first_loss_);
  EXPECT_LE(report_.test_pca_rel_l2, report_.test_p2s_rel_l2 + 1e-6);
  // The network must win at least half of what the basis can over the mean
  // PSF (an untrained network gets nothing: measured 0.71 at 150 steps).
  EXPECT_GT(report_.test_mean_rel_l2 - report_.test_p2s_rel_l2,
            0.5 * (report_.test_mean_rel_l2 - report_.test_pca_rel_l2));
  EXPECT_LT(std::abs(report_.train_p2s_rel_l2 - report_.test_p2s_rel_l2),
            0.25 * report_.test_p2s_rel_l2);  // 150 steps over 1024 pairs: no gross overfit
                                              // (measured 0.32 vs 0.35)
}

TEST_F(P2s, ArtifactRoundTrip) {
  const fs::path p = saved("model.safetensors");
  const P2sModel m = load_p2s_model(test::device(), p);
  EXPECT_EQ(m.basis.size, basis_->size);
  EXPECT_EQ(m.basis.j_max, basis_->j_max);
  EXPECT_EQ(m.basis.nyquist, basis_->nyquist);  // %.17g: exact
  EXPECT_EQ(m.basis.kernels, basis_->kernels);
  EXPECT_EQ(m.basis.variances, basis_->variances);
  EXPECT_EQ(m.net->config().output_scale, net_->config().output_scale);
  EXPECT_EQ(m.net->config().hidden, net_->config().hidden);
  Rng rng(5);
  const std::vector<double> a = draw_aberrations(rng, NollSampler(kJMax), 0.5, 8, 16);
  EXPECT_EQ(predict_betas(test::device(), *m.net, a), predict_betas(test::device(), *net_, a));
  bool leftover = false;
  for (const auto& e : fs::directory_iterator(dir_))
    leftover |= e.path().filename().string().find(".tmp") != std::string::npos;
  EXPECT_FALSE(leftover);
}

TEST_F(P2s, TruncatedFileIsRejected) {
  const fs::path p = saved("truncated.safetensors");
  fs::resize_file(p, fs::file_size(p) / 2);
  expect_load_error(p, "");
  expect_load_error(dir_ / "missing.safetensors", "");
}

TEST_F(P2s, WrongShapesAreRejected) {
  expect_load_error(edited("shape1.safetensors",
                           [](auto& t) {
                             auto& w = t.at("p2s.l2.weight");
                             w.shape = {w.shape[1] / 2, w.shape[0] * 2};
                           }),
                    "p2s.l2.weight");
  expect_load_error(edited("shape2.safetensors",
                           [](auto& t) {
                             auto& k = t.at("basis.kernels");
                             k.shape = {k.shape[0] * 15, k.shape[1] / 15 * 1, k.shape[2]};
                           }),
                    "basis.kernels");
  expect_load_error(edited("missing.safetensors", [](auto& t) { t.erase("p2s.l3.bias"); }),
                    "p2s.l3.bias");
  expect_load_error(edited("extra.safetensors",
                           [](auto& t) {
                             t["p2s.l4.weight"] = vkjr2::HostTensor{{1}, {0.f}};
                           }),
                    "p2s.l4.weight");
}

TEST_F(P2s, NonFiniteValuesAreRejected) {
  expect_load_error(edited("nan.safetensors",
                           [](auto& t) {
                             t.at("p2s.l1.weight").values[3] =
                                 std::numeric_limits<float>::quiet_NaN();
                           }),
                    "non-finite");
  expect_load_error(edited("inf.safetensors",
                           [](auto& t) {
                             t.at("basis.kernels").values[0] =
                                 std::numeric_limits<float>::infinity();
                           }),
                    "basis.kernels");
}

TEST_F(P2s, OtherSafetensorsFilesAreRejected) {
  const fs::path p = dir_ / "other.safetensors";
  nets::write_safetensors_f32(p, {{"w", vkjr2::HostTensor{{2}, {1.f, 2.f}}}});
  expect_load_error(p, "format");
}

TEST(P2sArtifact, MakeEndToEnd) {
  const fs::path out =
      fs::temp_directory_path() / ("vkjr2_p2s_make_" + std::to_string(::getpid()) + ".safetensors");
  Params params = preset("moderate");
  params.zernike_modes = 15;
  P2sArtifactConfig config;
  config.basis = tiny_basis_config();
  config.basis.samples = 200;
  config.train = tiny_train_config();
  config.train.steps = 20;
  config.train.train_samples = 256;
  config.train.test_samples = 32;
  config.hidden = 32;
  int calls = 0;
  const P2sTrainReport r =
      make_p2s_artifact(test::device(), params, config, out, [&](const P2sProgress&) { ++calls; });
  EXPECT_GT(calls, 3);
  EXPECT_EQ(r.steps, 20);
  EXPECT_GT(r.basis_seconds, 0);
  EXPECT_GE(r.total_seconds, r.basis_seconds + r.train_seconds);
  EXPECT_TRUE(std::isfinite(r.test_p2s_rel_l2));
  const P2sModel m = load_p2s_model(test::device(), out);
  EXPECT_NEAR(m.basis.nyquist, derive(params).channels[0].nyquist, 1e-15);
  EXPECT_EQ(m.basis.j_max, 15);
  EXPECT_EQ(m.net->config().hidden, 32);
  EXPECT_EQ(m.basis.count(), 12);
  fs::remove(out);
  config.channel = 3;
  EXPECT_THROW(make_p2s_artifact(test::device(), params, config, out), InvalidArgument);
}

}  // namespace
}  // namespace vkjr2::sim
