#include <vkjr2/kernels/mix.hpp>
#include <vkjr2/kernels/ref/mix_ref.hpp>
#include <vkjr2/runtime/error.hpp>

#include <gtest/gtest.h>

#include <random>

#include "support/op_check.hpp"
#include "support/test_device.hpp"

namespace vkjr2 {
namespace {

TEST(MixPlanes, MatchesReferenceOnRandomShapes) {
  Device& dev = test::device();
  std::mt19937 rng(31);
  for (int trial = 0; trial < 6; ++trial) {
    const std::int64_t k = std::uniform_int_distribution<std::int64_t>(2, 40)(rng);
    const std::int64_t b = std::uniform_int_distribution<std::int64_t>(1, 3)(rng);
    const std::int64_t h = std::uniform_int_distribution<std::int64_t>(1, 37)(rng);
    const std::int64_t w = std::uniform_int_distribution<std::int64_t>(1, 41)(rng);
    kernels::MixPlanesParams p;
    p.batch = b;
    p.out_h = std::uniform_int_distribution<std::int64_t>(1, h)(rng);
    p.out_w = std::uniform_int_distribution<std::int64_t>(1, w)(rng);
    p.scale = 1.7f;
    p.first2_scale = {-0.5f, 2.f};
    SCOPED_TRACE("k=" + std::to_string(k) + " b=" + std::to_string(b) + " " + std::to_string(h) +
                 "x" + std::to_string(w) + " seed=31 trial=" + std::to_string(trial));
    const auto planes = test::random_floats(std::size_t(k * b * h * w * 2), 100 + trial);
    auto mix = test::random_floats(std::size_t(k * k), 200 + trial);
    mix[0] = 0.f;  // zeros are skipped by the shader; the result must not change
    Tensor tp = Tensor::from(dev, {k * b, h, w, 2}, planes);
    Tensor tm = Tensor::from(dev, {k, k}, mix);
    Tensor out = Tensor::empty(dev, {b, k, p.out_h, p.out_w});
    Tensor f2 = Tensor::empty(dev, {b, 2, p.out_h, p.out_w});
    Tensor out2 = Tensor::empty(dev, {b, k, p.out_h, p.out_w});
    Stream s(dev);
    kernels::mix_planes(s, tp, tm, out, p, &f2);
    kernels::mix_planes(s, tp, tm, out2, p);
    s.run();
    std::vector<float> want, want2;
    ref::mix_planes(planes, h, w, mix, k, p, want, want2);
    test::expect_all_close("out", out.download(), want, {1e-4, 1e-5});
    test::expect_all_close("out2", out2.download(), want, {1e-4, 1e-5});
    test::expect_all_close("f2", f2.download(), want2, {1e-4, 1e-5});
  }
}

TEST(MixPlanes, BadShapesAreClearErrors) {
  Device& dev = test::device();
  Tensor planes = Tensor::empty(dev, {6, 8, 8, 2});
  Tensor mix = Tensor::empty(dev, {3, 3});
  Tensor out = Tensor::empty(dev, {2, 3, 4, 4});
  Stream s(dev);
  kernels::MixPlanesParams p;
  p.batch = 2;
  p.out_h = p.out_w = 4;
  EXPECT_NO_THROW(kernels::mix_planes(s, planes, mix, out, p));
  p.out_h = 9;
  EXPECT_THROW(kernels::mix_planes(s, planes, mix, out, p), InvalidArgument);
  p.out_h = 4;
  p.batch = 3;
  EXPECT_THROW(kernels::mix_planes(s, planes, mix, out, p), InvalidArgument);
  p.batch = 2;
  Tensor wrong = Tensor::empty(dev, {2, 2, 3, 4});
  EXPECT_THROW(kernels::mix_planes(s, planes, mix, out, p, &wrong), InvalidArgument);
  Tensor rect = Tensor::empty(dev, {3, 2});
  EXPECT_THROW(kernels::mix_planes(s, planes, rect, out, p), InvalidArgument);
  s.run();
}

}  // namespace
}  // namespace vkjr2
