// Planes: making zero-bordered planes and copying the image out of them, on
// random shapes and layouts, against the host.
#include <vkjr2/kernels/planes.hpp>
#include <vkjr2/runtime/error.hpp>

#include <gtest/gtest.h>

#include <random>

#include "support/test_device.hpp"

namespace vkjr2 {
namespace {

using kernels::PlaneLayout;
using kernels::Planes;

TEST(Planes, MakeZeroFillsAndUnpadCopiesTheInterior) {
  Device& dev = test::device();
  std::mt19937 rng(31);
  auto uni = [&](int lo, int hi) { return std::uniform_int_distribution<int>(lo, hi)(rng); };
  for (int trial = 0; trial < 12; ++trial) {
    const Shape s{uni(1, 2), uni(1, 5), uni(1, 13), uni(1, 17)};
    const PlaneLayout l{std::uint32_t(s[2] + uni(0, 4)), std::uint32_t(s[3] + uni(0, 6)), 0, 0};
    PlaneLayout at = l;
    at.top = uni(0, int(l.hp - s[2]));
    at.left = uni(0, int(l.wp - s[3]));
    SCOPED_TRACE(s.str() + " in " + at.str());
    Stream stream(dev);
    const Planes zeros = Planes::make(stream, s, at);
    ASSERT_TRUE(zeros.padded());
    ASSERT_EQ(zeros.data.numel(), s[0] * s[1] * at.hp * at.wp);
    // Random planes, border included: unpad reads the interior only.
    const auto host = test::random_floats(std::size_t(zeros.data.numel()), 40 + trial);
    const Planes p{Tensor::from(dev, zeros.data.shape(), host), s, at};
    EXPECT_EQ(kernels::layout_misfit(s, at), "");
    const Tensor plain = kernels::unpad(stream, p);
    stream.run();
    for (float v : zeros.data.download()) ASSERT_EQ(v, 0.f);
    ASSERT_EQ(plain.shape(), s);
    const auto got = plain.download();
    for (std::int64_t pl = 0; pl < s[0] * s[1]; ++pl) {
      for (std::int64_t y = 0; y < s[2]; ++y) {
        for (std::int64_t x = 0; x < s[3]; ++x) {
          const auto src = std::size_t((pl * at.hp + y + at.top) * at.wp + x + at.left);
          ASSERT_EQ(got[std::size_t((pl * s[2] + y) * s[3] + x)], host[src]);
        }
      }
    }
  }
}

TEST(Planes, PlainPlanesAreTheTensorAndBadLayoutsAreErrors) {
  Device& dev = test::device();
  Stream stream(dev);
  const Tensor x = Tensor::from(dev, {1, 2, 3, 4}, test::random_floats(24, 5));
  const Planes p = Planes::of(x);
  EXPECT_FALSE(p.padded());
  const Tensor same = kernels::unpad(stream, p);  // no copy
  EXPECT_EQ(same.vk_buffer(), x.vk_buffer());
  EXPECT_EQ(same.vk_offset(), x.vk_offset());
  EXPECT_EQ(p.geometry(), (PlaneLayout{3, 4, 0, 0}));
  // A layout that leaves rows out (a strided conv's) can be made, not unpadded.
  const Planes cropped = Planes::make(stream, {1, 2, 3, 4}, PlaneLayout{2, 8, 0, 1});
  EXPECT_NE(kernels::layout_misfit({1, 2, 3, 4}, cropped.layout), "");
  EXPECT_THROW(kernels::unpad(stream, cropped), InvalidArgument);
  EXPECT_THROW(Planes::make(stream, {2, 3, 4}, PlaneLayout{8, 8, 0, 0}), InvalidArgument);
  EXPECT_THROW(Planes::make(stream, {1, 2, 3, 4}, PlaneLayout{8, 8, -1, 0}), InvalidArgument);
}

}  // namespace
}  // namespace vkjr2
