#include <vkjr2/jr2/align.hpp>
#include <vkjr2/runtime/error.hpp>

#include <gtest/gtest.h>

#include <cmath>
#include <numbers>

#include "support/gradcheck.hpp"
#include "support/test_device.hpp"

namespace vkjr2::jr2 {
namespace {

// Flat index of an int index expression (test shapes are small).
std::size_t flat(std::int64_t i) { return static_cast<std::size_t>(i); }

TEST(Jr2Align, FitSimilarityRecoversAKnownTransform) {
  const double angle = 0.3, scale = 1.7;
  const Similarity truth{scale * std::cos(angle), scale * std::sin(angle), 12.5, -3.25};
  std::vector<Point2> src, dst;
  for (const Point2& p : kArcFace112) {
    src.push_back(p);
    dst.push_back(truth.apply(p));
  }
  const Similarity s = fit_similarity(src, dst);
  EXPECT_NEAR(s.a, truth.a, 1e-12);
  EXPECT_NEAR(s.b, truth.b, 1e-12);
  EXPECT_NEAR(s.tx, truth.tx, 1e-9);
  EXPECT_NEAR(s.ty, truth.ty, 1e-9);
  const Point2 back = s.inverse().apply(s.apply({3, 4}));
  EXPECT_NEAR(back.x, 3, 1e-12);
  EXPECT_NEAR(back.y, 4, 1e-12);
}

TEST(Jr2Align, FivePointsFromSixtyEightLandmarks) {
  std::vector<float> lm(136);
  for (int i = 0; i < 68; ++i) {
    lm[flat(2 * i)] = float(i);
    lm[flat(2 * i + 1)] = float(100 + i);
  }
  const auto p = five_points(lm);
  EXPECT_DOUBLE_EQ(p[0].x, 38.5);  // mean of 36..41
  EXPECT_DOUBLE_EQ(p[1].y, 144.5);
  EXPECT_DOUBLE_EQ(p[2].x, 30);
  EXPECT_DOUBLE_EQ(p[3].x, 48);
  EXPECT_DOUBLE_EQ(p[4].y, 154);
  lm[5] = std::nanf("");
  EXPECT_THROW(five_points(lm), InvalidArgument);
  EXPECT_THROW(five_points(std::span(lm).first(10)), InvalidArgument);
  const std::vector<Point2> same(3, Point2{1, 1});
  EXPECT_THROW(fit_similarity(same, same), InvalidArgument);
}

// Bilinear sample of channel c at image pixel (x, y), zeros outside.
float sample(const std::vector<float>& img, int c, int h, int w, double x, double y) {
  const int x0 = int(std::floor(x)), y0 = int(std::floor(y));
  const double fx = x - x0, fy = y - y0;
  double v = 0;
  for (int dy = 0; dy < 2; ++dy)
    for (int dx = 0; dx < 2; ++dx) {
      const int xx = x0 + dx, yy = y0 + dy;
      if (xx < 0 || yy < 0 || xx >= w || yy >= h) continue;
      v += (dx ? fx : 1 - fx) * (dy ? fy : 1 - fy) * img[flat((c * h + yy) * w + xx)];
    }
  return float(v);
}

TEST(Jr2Align, CropSamplesTheImageAtTheInverseTransform) {
  const int h = 37, w = 53, size = 24;
  const std::vector<float> img = test::random_floats(flat(3 * h * w), 9, 0.f, 255.f);
  const Similarity to_crop{0.6 * std::cos(0.2), 0.6 * std::sin(0.2), -4.0, 2.5};
  Stream s(test::device());
  nets::Tape t(s, false);
  const nets::Var crop =
      align_crop(t, nets::Var(Tensor::from(test::device(), Shape{1, 3, h, w}, img)), to_crop, size);
  s.run();
  const auto got = crop.value().download();
  const Similarity inv = to_crop.inverse();
  for (int c = 0; c < 3; ++c)
    for (int v = 0; v < size; ++v)
      for (int u = 0; u < size; ++u) {
        const Point2 p = inv.apply({double(u), double(v)});
        ASSERT_NEAR(got[std::size_t((c * size + v) * size + u)], sample(img, c, h, w, p.x, p.y),
                    2e-2)
            << "c " << c << " u " << u << " v " << v;
      }
}

TEST(Jr2Align, CropIsDifferentiableWithRespectToThePixels) {
  const int h = 20, w = 18, size = 9;
  const std::vector<float> img = test::random_floats(flat(3 * h * w), 10);
  std::vector<float> lm(136);
  for (int i = 0; i < 136; ++i) lm[std::size_t(i)] = float(3 + (i * 7) % 13);
  const Device& d = test::device();
  const std::vector<float> wts = test::random_floats(flat(3 * size * size), 11);
  Stream s(d);
  nets::Tape t(s);
  const nets::Var x(Tensor::from(d, Shape{1, 3, h, w}, img), true);
  const nets::Var crop = align_face(t, x, lm, size);
  t.backward(nets::sum_all(t, nets::mul(t, crop, nets::Var(Tensor::from(d, crop.shape(), wts)))));
  s.run();
  const auto analytic = x.grad().download();
  test::expect_gradient_matches(
      [&](std::span<const float> probe) {
        Stream s2(d);
        nets::Tape t2(s2, false);
        const nets::Var c =
            align_face(t2, nets::Var(Tensor::from(d, Shape{1, 3, h, w}, probe)), lm, size);
        s2.run();
        return test::weighted_sum(c.value().download(), wts);
      },
      img, analytic, "align_face d/dimage");
}

}  // namespace
}  // namespace vkjr2::jr2
