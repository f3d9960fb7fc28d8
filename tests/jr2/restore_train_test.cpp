#include <vkjr2/jr2/benchmark.hpp>
#include <vkjr2/jr2/restore_train.hpp>
#include <vkjr2/nets/ops.hpp>
#include <vkjr2/sim/p2s_blur_model.hpp>
#include <vkjr2/sim/simulator.hpp>

#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <memory>
#include <string>
#include <vector>

#include "support/expect_error.hpp"
#include "support/gradcheck.hpp"
#include "support/temp_dir.hpp"
#include "support/test_device.hpp"

namespace vkjr2::jr2 {
namespace {

// A tiny network and 16² clips: the whole loop in seconds.
RestoreTrainOptions tiny() {
  RestoreTrainOptions o;
  o.net = {2, 4, {1}, 0, {1}};
  o.crop = 16;
  o.batch = 2;
  o.steps = 3;
  o.warmup_steps = 1;
  o.pool = 3;
  o.refresh = 1;
  o.val_clips = 2;
  o.seed = 11;
  return o;
}

std::vector<TrainImage> images(int count, std::uint32_t seed) {
  std::vector<TrainImage> out;
  for (int i = 0; i < count; ++i) {
    out.push_back(
        {"random" + std::to_string(i),
         {{24, 20, 3}, test::random_floats(24 * 20 * 3, seed + std::uint32_t(i), 0, 255)}});
  }
  return out;
}

std::unique_ptr<RestoreTrainer> trainer(const RestoreTrainOptions& o) {
  Device& dev = test::device();
  return std::make_unique<RestoreTrainer>(dev, o, images(3, 5), images(1, 50),
                                          sim::load_shipped_blur_models(dev));
}

std::vector<std::vector<float>> weights(const RestoreTrainer& t) {
  std::vector<std::vector<float>> out;
  for (const auto& [name, v] : t.restorer().named_parameters()) out.push_back(v.value().download());
  return out;
}

// A run stopped after two steps (its checkpoint at ckpt) and a new trainer
// resumed from it.
std::unique_ptr<RestoreTrainer> resumed_after_two(const RestoreTrainOptions& o,
                                                  const std::filesystem::path& ckpt) {
  {
    auto first = trainer(o);
    first->train_step();
    first->train_step();
    first->save_checkpoint(ckpt);
  }
  auto resumed = trainer(o);
  resumed->load_checkpoint(ckpt);
  EXPECT_EQ(resumed->step(), 2);
  return resumed;
}

TEST(RestoreTrainer, ResumesFromACheckpointBitExactly) {
  const RestoreTrainOptions o = tiny();
  auto straight = trainer(o);
  std::vector<RestoreStepReport> reports;
  for (int i = 0; i < 3; ++i) reports.push_back(straight->train_step());
  for (const auto& r : reports) {
    EXPECT_TRUE(std::isfinite(r.loss) && r.loss > 0) << r.step;
    EXPECT_GT(r.grad_norm, 0) << r.step;
  }
  EXPECT_EQ(reports.back().step, 3);

  test::TempDir dir;
  const auto ckpt = dir.path / "run.ckpt";
  auto resumed = resumed_after_two(o, ckpt);
  const RestoreStepReport last = resumed->train_step();
  EXPECT_EQ(last.loss, reports.back().loss);
  EXPECT_EQ(last.lr, reports.back().lr);
  EXPECT_EQ(weights(*resumed), weights(*straight));

  // The held-out clips are fixed: the degraded scores do not depend on training.
  const RestoreEvalReport a = straight->evaluate(), b = resumed->evaluate();
  EXPECT_EQ(a.psnr_degraded, b.psnr_degraded);
  EXPECT_EQ(a.psnr_restored, b.psnr_restored);
  EXPECT_TRUE(std::isfinite(a.psnr_restored) && std::isfinite(a.ssim_restored));
  EXPECT_GT(a.psnr_degraded, 5.0);
}

// Explicit modeling on the simpler simulator: the consistency term is
// reported, and a resumed run still equals the straight one.
TEST(RestoreTrainer, ExplicitTrainingResumesBitExactly) {
  RestoreTrainOptions o = tiny();
  o.explicit_weight = 0.5f;
  o.correlate_high_order = false;
  auto straight = trainer(o);
  RestoreStepReport last;
  for (int i = 0; i < 3; ++i) last = straight->train_step();
  EXPECT_TRUE(std::isfinite(last.consistency) && last.consistency > 0);
  EXPECT_GT(last.loss, last.consistency * 0.5);  // the total holds the weighted term
  test::TempDir dir;
  const auto ckpt = dir.path / "run.ckpt";
  auto resumed = resumed_after_two(o, ckpt);
  const RestoreStepReport again = resumed->train_step();
  EXPECT_EQ(again.loss, last.loss);
  EXPECT_EQ(again.consistency, last.consistency);
  EXPECT_EQ(weights(*resumed), weights(*straight));
  // A checkpoint of the internalizing run is refused.
  RestoreTrainOptions plain = tiny();
  plain.correlate_high_order = false;
  auto other = trainer(plain);
  test::expect_invalid_argument([&] { other->load_checkpoint(ckpt); }, "train.explicit_weight");
}

// redegrade is Simulator::frame for the frame's own maps, forward and
// backward, and its gradient matches central differences.
TEST(Redegrade, IsTheSimulatorsFrameAndItsBackward) {
  Device& dev = test::device();
  constexpr int kSide = 24;
  const sim::Params p = probe_sim_params(5.0, kSide);
  sim::Simulator simulator(dev, p, sim::load_shipped_blur_models(dev), probe_sim_options());
  const Shape shape{1, 3, kSide, kSide};
  const std::vector<float> xs = test::random_floats(std::size_t(shape.numel()), 3, 0, 1);
  const std::vector<float> w = test::random_floats(std::size_t(shape.numel()), 4);
  const Tensor x = Tensor::from(dev, shape, xs), y = Tensor::empty(dev, shape);
  const Tensor dy = Tensor::from(dev, shape, w), dx = Tensor::empty(dev, shape);
  simulator.reset(9);
  Stream stream(dev);
  simulator.frame(stream, x, y);
  simulator.frame(stream, x, y);  // frame 1: the AR(1) successor
  simulator.frame_backward(stream, dy, dx);
  stream.run();
  const Tensor& basis = simulator.blur_model(0)->basis();
  const Tensor flow = simulator.flow(), beta = simulator.beta();

  nets::Tape tape(stream);
  const nets::Var xv(x, true);
  const nets::Var out = redegrade(tape, xv, flow, beta, basis);
  tape.backward(nets::sum_all(tape, nets::mul(tape, out, nets::Var(dy))));
  stream.run();
  const auto want = y.download(), got = out.value().download();
  const auto want_dx = dx.download(), got_dx = xv.grad().download();
  for (std::size_t i = 0; i < want.size(); ++i) {
    ASSERT_NEAR(got[i], want[i], 1e-5) << "y[" << i << "]";
    ASSERT_NEAR(got_dx[i], want_dx[i], 1e-5 * (1 + std::fabs(want_dx[i]))) << "dx[" << i << "]";
  }
  const auto forward = [&](std::span<const float> v) {
    Stream s(dev);
    nets::Tape inference(s, false);
    const nets::Var o =
        redegrade(inference, nets::Var(Tensor::from(dev, shape, v)), flow, beta, basis);
    s.run();
    return test::weighted_sum(o.value().download(), w);
  };
  test::expect_gradient_matches(forward, xs, got_dx, "redegrade d/x");

  test::expect_invalid_argument(
      [&] {
        nets::Tape t(stream);
        (void)redegrade(t, xv, beta, beta, basis);
      },
      "flow");
}

TEST(RestoreTrainer, RefusesACheckpointOfOtherSettings) {
  test::TempDir dir;
  const auto ckpt = dir.path / "run.ckpt";
  trainer(tiny())->save_checkpoint(ckpt);
  RestoreTrainOptions other = tiny();
  other.lr = 5e-4f;
  auto t = trainer(other);
  test::expect_invalid_argument([&] { t->load_checkpoint(ckpt); }, "train.lr");
}

TEST(RestoreTrainer, BadOptionsAndImagesAreClearErrors) {
  Device& dev = test::device();
  auto with = [](auto change) {
    RestoreTrainOptions o = tiny();
    change(o);
    return o;
  };
  test::expect_invalid_argument(
      [&] { with([](RestoreTrainOptions& o) { o.crop = 18; }).validate(); }, "--crop");
  test::expect_invalid_argument(
      [&] { with([](RestoreTrainOptions& o) { o.pool = 1; }).validate(); }, "--pool");
  test::expect_invalid_argument(
      [&] { with([](RestoreTrainOptions& o) { o.lr = NAN; }).validate(); }, "--lr");
  test::expect_invalid_argument(
      [&] { with([](RestoreTrainOptions& o) { o.d_over_r0_lo = 0; }).validate(); }, "D/r0");
  test::expect_invalid_argument(
      [&] { with([](RestoreTrainOptions& o) { o.explicit_weight = -1; }).validate(); },
      "--explicit");
  const auto blur = sim::load_shipped_blur_models(dev);
  std::vector<TrainImage> small = {{"tiny.png", {{8, 8, 3}, std::vector<float>(192, 1.f)}}};
  test::expect_invalid_argument([&] { RestoreTrainer(dev, tiny(), small, images(1, 2), blur); },
                                "tiny.png");
  test::expect_invalid_argument([&] { RestoreTrainer(dev, tiny(), images(1, 2), {}, blur); },
                                "held-out");
}

TEST(RestoreWindow, CentresTheFrameAndClampsAtTheEnds) {
  EXPECT_EQ(restore_window(30, 15, 8), (std::vector<std::size_t>{11, 12, 13, 14, 15, 16, 17, 18}));
  EXPECT_EQ(restore_window(30, 0, 4), (std::vector<std::size_t>{0, 0, 0, 1}));
  EXPECT_EQ(restore_window(30, 29, 4), (std::vector<std::size_t>{27, 28, 29, 29}));
  EXPECT_EQ(restore_window(1, 0, 3), (std::vector<std::size_t>{0, 0, 0}));
  test::expect_invalid_argument([] { (void)restore_window(3, 3, 8); }, "index");
}

}  // namespace
}  // namespace vkjr2::jr2
