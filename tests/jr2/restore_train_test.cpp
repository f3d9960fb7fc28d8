#include <vkjr2/jr2/restore_train.hpp>
#include <vkjr2/sim/p2s_blur_model.hpp>

#include <gtest/gtest.h>

#include <cmath>
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
  {
    auto first = trainer(o);
    first->train_step();
    first->train_step();
    first->save_checkpoint(ckpt);
  }
  auto resumed = trainer(o);
  resumed->load_checkpoint(ckpt);
  EXPECT_EQ(resumed->step(), 2);
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
