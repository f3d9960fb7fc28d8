// Wave-optics clip sets: made, saved, read back and scored.
#include <vkjr2/jr2/clip_set.hpp>
#include <vkjr2/kernels/metrics.hpp>

#include <gtest/gtest.h>

#include <cmath>
#include <fstream>
#include <string>
#include <vector>

#include "support/expect_error.hpp"
#include "support/temp_dir.hpp"
#include "support/test_device.hpp"

namespace vkjr2::jr2 {
namespace {

std::vector<TrainImage> images() {
  std::vector<TrainImage> out;
  for (std::uint32_t i = 0; i < 2; ++i) {
    out.push_back({"img" + std::to_string(i),
                   {{40, 48, 3}, test::random_floats(40 * 48 * 3, 70 + i, 0, 255)}});
  }
  return out;
}

WaveClipOptions tiny() {
  WaveClipOptions o;
  o.clips = 3;
  o.frames = 2;
  o.size = 24;
  o.d_over_r0_lo = 2;
  o.d_over_r0_hi = 6;
  o.wave.wave.screens = 2;
  return o;
}

TEST(ClipSet, WaveClipsRoundTripAndScore) {
  Device& dev = test::device();
  const WaveClipOptions o = tiny();
  const ClipSet set = make_wave_clips(dev, images(), o);
  ASSERT_EQ(set.count(), 3u);
  EXPECT_EQ(set.degraded.size(), 3u * 2 * 3 * 24 * 24);
  EXPECT_NEAR(set.d_over_r0.front(), 2.0, 1e-12);
  EXPECT_NEAR(set.d_over_r0.back(), 6.0, 1e-12);
  EXPECT_EQ(set.sources, (std::vector<std::string>{"img0", "img1", "img0"}));
  // The clean frame is the held-out crop; frames differ (own screens) and
  // stay in 0..1; clips 0 and 2 share an image but not the turbulence.
  const std::vector<float> crop = held_out_crop(images()[0].rgb, 24);
  EXPECT_TRUE(std::equal(crop.begin(), crop.end(), set.clean.begin()));
  const std::size_t f = 3 * 24 * 24;
  double diff = 0, err = 0;
  for (std::size_t k = 0; k < f; ++k) {
    diff += std::fabs(set.degraded[k] - set.degraded[f + k]);
    err += std::fabs(set.degraded[k] - set.clean[k]);
    ASSERT_TRUE(set.degraded[k] >= 0 && set.degraded[k] <= 1) << k;
  }
  EXPECT_GT(diff / double(f), 1e-3);
  EXPECT_GT(err / double(f), 1e-3);
  // Same seed, same set.
  EXPECT_EQ(make_wave_clips(dev, images(), o).degraded, set.degraded);

  test::TempDir dir;
  const auto path = dir.path / "clips.safetensors";
  save_clip_set(path, set);
  const ClipSet back = load_clip_set(path);
  EXPECT_EQ(back.degraded, set.degraded);
  EXPECT_EQ(back.clean, set.clean);
  EXPECT_EQ(back.sources, set.sources);
  EXPECT_EQ(back.frames, 2);
  EXPECT_EQ(back.size, 24);
  EXPECT_EQ(back.metadata.at("source"), "wave-optics");

  // Scores: the degraded row is the PSNR of the reference frame (T / 2 = 1);
  // a network of 3 frames reads a clamped window.
  const Restorer net(dev, {3, 4, {1}, 0, {1}}, 5);
  const auto rows = score_clip_set(dev, back, {&net}, {"tiny"}, {}, {.resamples = 50});
  ASSERT_EQ(rows.size(), 3u);
  EXPECT_EQ(rows[0].method, "degraded");
  EXPECT_EQ(rows[1].method, "classical");
  EXPECT_EQ(rows[2].method, "tiny");
  for (std::size_t i = 0; i < set.count(); ++i) {
    double mse = 0;
    for (std::size_t k = 0; k < f; ++k) {
      const double d = set.degraded[(i * 2 + 1) * f + k] - set.clean[i * f + k];
      mse += d * d;
    }
    EXPECT_NEAR(rows[0].psnr[i], 10 * std::log10(1.0 / (mse / double(f))), 1e-3) << i;
  }
  EXPECT_EQ(rows[0].psnr_gain.value, 0.0);
  for (const auto& r : rows) {
    EXPECT_TRUE(std::isfinite(r.psnr_mean.value) && r.psnr_mean.lo <= r.psnr_mean.value &&
                r.psnr_mean.value <= r.psnr_mean.hi)
        << r.method;
    EXPECT_EQ(r.psnr.size(), 3u);
  }
}

// Frozen flow: a clip's frames share its screens, so a vanishing motion
// gives the same frame again, a real one another frame.
TEST(ClipSet, FrozenFlowFramesShareTheClipsScreens) {
  Device& dev = test::device();
  WaveClipOptions o = tiny();
  o.clips = 1;
  o.screen_motion_m = 1e-7;
  const ClipSet still = make_wave_clips(dev, images(), o);
  o.screen_motion_m = 0.04;
  const ClipSet moving = make_wave_clips(dev, images(), o);
  const std::size_t f = 3 * 24 * 24;
  double still_diff = 0, moving_diff = 0;
  for (std::size_t k = 0; k < f; ++k) {
    still_diff = std::max(still_diff, double(std::fabs(still.degraded[k] - still.degraded[f + k])));
    moving_diff += std::fabs(moving.degraded[k] - moving.degraded[f + k]);
    ASSERT_EQ(still.degraded[k], moving.degraded[k]) << k;  // frame 0: the screens as drawn
  }
  EXPECT_LT(still_diff, 1e-3);
  EXPECT_GT(moving_diff / double(f), 1e-3);
  EXPECT_EQ(moving.metadata.at("screen_motion_m"), "0.04");
  o.screen_motion_m = -1;
  test::expect_invalid_argument([&] { o.validate(); }, "--screen-motion");
}

TEST(ClipSet, BadFilesAndOptionsAreClearErrors) {
  Device& dev = test::device();
  test::TempDir dir;
  const auto path = dir.path / "not_clips.safetensors";
  const Restorer net(dev, {2, 4, {1}, 0, {1}}, 5);
  net.save(path);
  test::expect_invalid_argument([&] { (void)load_clip_set(path); }, "not a clip set");
  WaveClipOptions o = tiny();
  o.clips = 0;
  test::expect_invalid_argument([&] { o.validate(); }, "--clips");
  o = tiny();
  o.d_over_r0_hi = 1;
  test::expect_invalid_argument([&] { o.validate(); }, "D/r0");
  std::vector<TrainImage> small = {{"small.png", {{10, 10, 3}, std::vector<float>(300, 1.f)}}};
  test::expect_invalid_argument([&] { (void)make_wave_clips(dev, small, tiny()); }, "small.png");
}

}  // namespace
}  // namespace vkjr2::jr2
