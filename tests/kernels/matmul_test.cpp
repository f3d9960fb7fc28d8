#include <vkjr2/kernels/matmul.hpp>
#include <vkjr2/kernels/ref/matmul_ref.hpp>

#include <gtest/gtest.h>

#include <chrono>
#include <cmath>
#include <cstdio>
#include <string>
#include <vector>

#include "support/gradcheck.hpp"
#include "support/op_check.hpp"
#include "support/test_device.hpp"

namespace vkjr2 {
namespace {

// fp32 dot products of length K: error ≤ ~K·eps·Σ|x||w|; 1e-4 of that scale is generous.
void expect_matmul_close(test::OpCase& c, const std::string& name, const Tensor& got,
                         const std::vector<float>& want, const std::vector<float>& abs_scale) {
  std::vector<double> bound(abs_scale.size());
  for (std::size_t i = 0; i < bound.size(); ++i) bound[i] = 1e-4 * abs_scale[i] + 1e-6;
  c.expect(name, got, want, bound);
}

// [M, K, N] of one product.
Shape mkn(test::OpCase& c, int max) {
  return {c.uniform(1, max), c.uniform(1, max), c.uniform(1, max)};
}

void check_case(test::OpCase& c, const Shape& mkn_shape) {
  const auto m = mkn_shape[0], k = mkn_shape[1], n = mkn_shape[2];
  const auto um = std::size_t(m), uk = std::size_t(k), un = std::size_t(n);
  c.describe("M " + std::to_string(m) + " K " + std::to_string(k) + " N " + std::to_string(n));
  const auto xv = c.floats(m * k), wv = c.floats(k * n);
  const auto bv = c.floats(n), dyv = c.floats(m * n);
  Tensor x = c.tensor({m, k}, xv), w = c.tensor({k, n}, wv);
  Tensor b = c.tensor({n}, bv), dy = c.tensor({m, n}, dyv);
  Tensor y = c.empty({m, n}), y0 = c.empty({m, n});
  Tensor dx = c.empty({m, k}), dw = c.empty({k, n}), db = c.empty({n});
  Stream s(c.device);
  kernels::matmul(s, x, w, y, &b);
  kernels::matmul(s, x, w, y0);
  kernels::matmul_backward(s, x, w, dy, &dx, &dw, &db);
  s.run();
  const auto scale = ref::matmul_abs(xv, wv, um, uk, un);
  expect_matmul_close(c, "y", y, ref::matmul(xv, wv, bv, um, uk, un), scale);
  expect_matmul_close(c, "y without bias", y0, ref::matmul(xv, wv, {}, um, uk, un), scale);
  const auto wt = ref::transpose(wv, uk, un), xt = ref::transpose(xv, um, uk);
  expect_matmul_close(c, "dx", dx, ref::matmul(dyv, wt, {}, um, un, uk),
                      ref::matmul_abs(dyv, wt, um, un, uk));
  expect_matmul_close(c, "dw", dw, ref::matmul(xt, dyv, {}, uk, um, un),
                      ref::matmul_abs(xt, dyv, uk, um, un));
  const std::vector<float> ones(um, 1.f);
  expect_matmul_close(c, "db", db, ref::matmul(ones, dyv, {}, 1, um, un),
                      ref::matmul_abs(ones, dyv, 1, um, un));
}

TEST(MatmulKernels, OddShapesMatchReference) {
  const std::int64_t dims[] = {1, 3, 17, 65, 130};
  // Every dimension takes each odd size at least once, in a 5 × 5 Latin-square pattern.
  std::vector<Shape> edges;
  for (std::size_t i = 0; i < 5; ++i) {
    for (std::size_t j = 0; j < 5; ++j) edges.push_back({dims[i], dims[j], dims[(i + j) % 5]});
  }
  test::check_op(
      "matmul odd shapes", {.seed = 51, .cases = int(edges.size()) + 4},
      [&](test::OpCase& c) { check_case(c, c.edge_or(edges, [&] { return mkn(c, 130); })); });
}

// The shader's variants: one row per tile (M < 4: a linear layer on one
// input, the landmark net's fc 256 → 136), B through a vec4 view (N a
// multiple of 8; the forward and dW), both, and neither. Random ones: M up
// to 9, N a multiple of 8 or not.
TEST(MatmulKernels, RowVectorsAndAlignedColumnsMatchReference) {
  const std::vector<Shape> edges = {{1, 256, 136}, {2, 33, 16}, {3, 8, 8}, {5, 40, 24},
                                    {1, 7, 9},     {4, 5, 32},  {9, 1, 8}};
  test::check_op("matmul row vectors, aligned columns",
                 {.seed = 54, .cases = int(edges.size()) + 4}, [&](test::OpCase& c) {
                   check_case(c, c.edge_or(edges, [&]() -> Shape {
                     const int m = c.uniform(1, 9), k = c.uniform(1, 256);
                     return {m, k, c.uniform(0, 1) ? 8 * c.uniform(1, 17) : c.uniform(1, 136)};
                   }));
                 });
}

TEST(MatmulKernels, LargeMatchesReference) {
  // The smaller first: the first case also runs on the other device paths.
  const std::vector<Shape> edges = {{64, 300, 129}, {256, 256, 256}};
  const int random_cases = 3;
  const auto t0 = std::chrono::steady_clock::now();
  test::check_op(
      "matmul large", {.seed = 52, .cases = int(edges.size()) + random_cases},
      [&](test::OpCase& c) { check_case(c, c.edge_or(edges, [&] { return mkn(c, 256); })); });
  const double s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  std::printf("[ matmul ] 64·300·129, 256³ and %d random with backward and references: %.2f s\n",
              random_cases, s);
}

TEST(MatmulKernels, GradientsMatchFiniteDifferences) {
  Device& dev = test::device();
  const std::int64_t m = 3, k = 5, n = 7;
  const std::uint32_t seed = 54;
  SCOPED_TRACE("seed " + std::to_string(seed));
  const auto xv = test::random_floats(15, seed), wv = test::random_floats(35, seed + 1);
  const auto bv = test::random_floats(7, seed + 2), gw = test::random_floats(21, seed + 3);
  Tensor x = Tensor::from(dev, {m, k}, xv), w = Tensor::from(dev, {k, n}, wv);
  Tensor b = Tensor::from(dev, {n}, bv), g = Tensor::from(dev, {m, n}, gw);
  Tensor dx = Tensor::empty(dev, {m, k}), dw = Tensor::empty(dev, {k, n}),
         db = Tensor::empty(dev, {n});
  {
    Stream s(dev);
    kernels::matmul_backward(s, x, w, g, &dx, &dw, &db);
    s.run();
  }
  auto loss = [&](std::span<const float> xs, std::span<const float> ws, std::span<const float> bs) {
    Tensor xt = Tensor::from(dev, {m, k}, xs), wt = Tensor::from(dev, {k, n}, ws);
    Tensor bt = Tensor::from(dev, {n}, bs), y = Tensor::empty(dev, {m, n});
    Stream s(dev);
    kernels::matmul(s, xt, wt, y, &bt);
    s.run();
    return test::weighted_sum(y.download(), gw);
  };
  test::expect_gradient_matches([&](std::span<const float> v) { return loss(v, wv, bv); }, xv,
                                dx.download(), "dx");
  test::expect_gradient_matches([&](std::span<const float> v) { return loss(xv, v, bv); }, wv,
                                dw.download(), "dw");
  test::expect_gradient_matches([&](std::span<const float> v) { return loss(xv, wv, v); }, bv,
                                db.download(), "dbias");
}

TEST(MatmulKernels, BadInputsAreClearErrors) {
  Device& dev = test::device();
  Stream s(dev);
  Tensor x = Tensor::empty(dev, {4, 5}), w = Tensor::empty(dev, {6, 3});
  Tensor w2 = Tensor::empty(dev, {5, 3}), y = Tensor::empty(dev, {4, 3});
  try {
    kernels::matmul(s, x, w, y);
    FAIL();
  } catch (const InvalidArgument& e) {
    EXPECT_NE(std::string(e.what()).find("inner dimensions"), std::string::npos) << e.what();
  }
  Tensor bad_bias = Tensor::empty(dev, {4});
  EXPECT_THROW(kernels::matmul(s, x, w2, y, &bad_bias), InvalidArgument);
  EXPECT_THROW(kernels::matmul(s, x, w2, x), InvalidArgument);
  EXPECT_THROW(kernels::matmul(s, Tensor::empty(dev, {20}), w2, y), InvalidArgument);
  EXPECT_THROW(kernels::matmul_backward(s, x, w2, x, &x, nullptr), InvalidArgument);
}

}  // namespace
}  // namespace vkjr2
