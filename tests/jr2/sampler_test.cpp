// The temporal frame sampler: the paper's 4 × 2 of 30 frames, uniform-K, all,
// seeding, short videos and the --frames syntax.
#include <vkjr2/jr2/sampler.hpp>
#include <vkjr2/runtime/error.hpp>

#include <gtest/gtest.h>

#include <algorithm>
#include <set>

namespace vkjr2::jr2 {
namespace {

TEST(FrameSampler, PaperSegmentsOfThirtyFrames) {
  const FrameSampler s;  // segments:4x2
  std::set<std::vector<int>> seen;
  for (std::uint64_t seed = 0; seed < 50; ++seed) {
    const std::vector<int> f = sample_frames(30, s, seed);
    ASSERT_EQ(f.size(), 8u);
    EXPECT_TRUE(std::is_sorted(f.begin(), f.end()));
    // Parts [0,7) [7,15) [15,22) [22,30): two consecutive frames inside each.
    const int bounds[5] = {0, 7, 15, 22, 30};
    for (std::size_t p = 0; p < 4; ++p) {
      const int a = f[2 * p], b = f[2 * p + 1];
      EXPECT_EQ(b, a + 1);
      EXPECT_GE(a, bounds[p]);
      EXPECT_LT(b, bounds[p + 1]);
    }
    EXPECT_EQ(sample_frames(30, s, seed), f);  // seeded
    seen.insert(f);
  }
  EXPECT_GT(seen.size(), 30u);  // the start is random
}

TEST(FrameSampler, ShortVideosUniformAndAll) {
  EXPECT_EQ(sample_frames(3, FrameSampler{}, 1), (std::vector<int>{0, 1, 2}));
  EXPECT_EQ(sample_frames(1, FrameSampler{}, 1), (std::vector<int>{0}));
  const FrameSampler u = parse_frame_sampler("uniform:4");
  EXPECT_EQ(sample_frames(30, u, 7), (std::vector<int>{3, 11, 18, 26}));
  EXPECT_EQ(sample_frames(2, u, 7), (std::vector<int>{0, 1}));
  EXPECT_EQ(sample_frames(4, parse_frame_sampler("all"), 7), (std::vector<int>{0, 1, 2, 3}));
}

TEST(FrameSampler, ParsesAndPrintsItsSyntax) {
  const FrameSampler s = parse_frame_sampler("segments:3x5");
  EXPECT_EQ(s.kind, SamplerKind::segments);
  EXPECT_EQ(s.segments, 3);
  EXPECT_EQ(s.run, 5);
  for (const char* text : {"segments:4x2", "uniform:8", "all"}) {
    EXPECT_EQ(to_string(parse_frame_sampler(text)), text);
  }
  for (const char* bad : {"", "segments:4", "segments:0x2", "segments:4x", "uniform:-1",
                          "uniform:8x", "every", "all:3"}) {
    EXPECT_THROW(parse_frame_sampler(bad), InvalidArgument) << bad;
  }
  EXPECT_THROW(sample_frames(0, FrameSampler{}, 1), InvalidArgument);
}

}  // namespace
}  // namespace vkjr2::jr2
