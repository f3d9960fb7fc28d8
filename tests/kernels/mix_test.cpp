#include <vkjr2/kernels/mix.hpp>
#include <vkjr2/kernels/ref/mix_ref.hpp>
#include <vkjr2/runtime/error.hpp>

#include <gtest/gtest.h>

#include <string>
#include <vector>

#include "support/op_check.hpp"
#include "support/test_device.hpp"

namespace vkjr2 {
namespace {

// k, batch, plane h × w, out_h × out_w.
struct Case {
  std::int64_t k, b, h, w, out_h, out_w;
};

// The smallest case (one 1×1 plane per image, k = 2), then random ones.
const std::vector<Case> kEdges = {{2, 1, 1, 1, 1, 1}};

Case draw_case(test::OpCase& c) {
  if (c.index < int(kEdges.size())) return kEdges[std::size_t(c.index)];
  auto uni = [&](std::int64_t lo, std::int64_t hi) {
    return std::int64_t(c.uniform(int(lo), int(hi)));
  };
  const std::int64_t k = uni(2, 40), b = uni(1, 3), h = uni(1, 37), w = uni(1, 41);
  return {k, b, h, w, uni(1, h), uni(1, w)};
}

TEST(MixPlanes, MatchesReferenceOnRandomShapes) {
  test::check_op("mix_planes", {.seed = 31, .cases = int(kEdges.size()) + 6}, [](test::OpCase& c) {
    const Case t = draw_case(c);
    const std::int64_t k = t.k, b = t.b, h = t.h, w = t.w;
    kernels::MixPlanesParams p;
    p.batch = b;
    p.out_h = t.out_h;
    p.out_w = t.out_w;
    p.scale = 1.7f;
    p.first2_scale = {-0.5f, 2.f};
    c.describe("k=" + std::to_string(k) + " b=" + std::to_string(b) + " " + std::to_string(h) +
               "x" + std::to_string(w) + " -> " + std::to_string(p.out_h) + "x" +
               std::to_string(p.out_w));
    const auto planes = c.floats(k * b * h * w * 2);
    auto mix = c.floats(k * k);
    mix[0] = 0.f;  // zeros are skipped by the shader; the result must not change
    Tensor tp = c.tensor({k * b, h, w, 2}, planes);
    Tensor tm = c.tensor({k, k}, mix);
    Tensor out = c.empty({b, k, p.out_h, p.out_w});
    Tensor f2 = c.empty({b, 2, p.out_h, p.out_w});
    Tensor out2 = c.empty({b, k, p.out_h, p.out_w});
    Stream s(c.device);
    kernels::mix_planes(s, tp, tm, out, p, &f2);
    kernels::mix_planes(s, tp, tm, out2, p);
    s.run();
    std::vector<float> want, want2;
    ref::mix_planes(planes, h, w, mix, k, p, want, want2);
    c.expect("out", out, want, {1e-4, 1e-5});
    c.expect("out2", out2, want, {1e-4, 1e-5});
    c.expect("f2", f2, want2, {1e-4, 1e-5});
  });
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
