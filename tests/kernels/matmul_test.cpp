#include <vkjr2/kernels/matmul.hpp>
#include <vkjr2/kernels/ref/matmul_ref.hpp>

#include <gtest/gtest.h>

#include <chrono>
#include <cmath>
#include <cstdio>
#include <string>
#include <vector>

#include "support/gradcheck.hpp"
#include "support/test_device.hpp"

namespace vkjr2 {
namespace {

// fp32 dot products of length K: error ≤ ~K·eps·Σ|x||w|; 1e-4 of that scale is generous.
void expect_matmul_close(const std::vector<float>& got, const std::vector<float>& want,
                         const std::vector<float>& abs_scale) {
  ASSERT_EQ(got.size(), want.size());
  for (std::size_t i = 0; i < got.size(); ++i) {
    ASSERT_NEAR(got[i], want[i], 1e-4 * abs_scale[i] + 1e-6) << "at " << i;
  }
}

struct Case {
  std::size_t m, k, n;
};

void check_case(const Case& c, std::uint32_t seed) {
  Device& dev = test::device();
  SCOPED_TRACE("M " + std::to_string(c.m) + " K " + std::to_string(c.k) + " N " +
               std::to_string(c.n) + " seed " + std::to_string(seed));
  const auto m = std::int64_t(c.m), k = std::int64_t(c.k), n = std::int64_t(c.n);
  const auto xv = test::random_floats(c.m * c.k, seed),
             wv = test::random_floats(c.k * c.n, seed + 1);
  const auto bv = test::random_floats(c.n, seed + 2),
             dyv = test::random_floats(c.m * c.n, seed + 3);
  Tensor x = Tensor::from(dev, {m, k}, xv), w = Tensor::from(dev, {k, n}, wv);
  Tensor b = Tensor::from(dev, {n}, bv), dy = Tensor::from(dev, {m, n}, dyv);
  Tensor y = Tensor::empty(dev, {m, n}), y0 = Tensor::empty(dev, {m, n});
  Tensor dx = Tensor::empty(dev, {m, k}), dw = Tensor::empty(dev, {k, n}),
         db = Tensor::empty(dev, {n});
  Stream s(dev);
  kernels::matmul(s, x, w, y, &b);
  kernels::matmul(s, x, w, y0);
  kernels::matmul_backward(s, x, w, dy, &dx, &dw, &db);
  s.run();
  const auto scale = ref::matmul_abs(xv, wv, c.m, c.k, c.n);
  expect_matmul_close(y.download(), ref::matmul(xv, wv, bv, c.m, c.k, c.n), scale);
  expect_matmul_close(y0.download(), ref::matmul(xv, wv, {}, c.m, c.k, c.n), scale);
  const auto wt = ref::transpose(wv, c.k, c.n), xt = ref::transpose(xv, c.m, c.k);
  expect_matmul_close(dx.download(), ref::matmul(dyv, wt, {}, c.m, c.n, c.k),
                      ref::matmul_abs(dyv, wt, c.m, c.n, c.k));
  expect_matmul_close(dw.download(), ref::matmul(xt, dyv, {}, c.k, c.m, c.n),
                      ref::matmul_abs(xt, dyv, c.k, c.m, c.n));
  std::vector<float> ones(c.m, 1.f);
  const auto rdb = ref::matmul(ones, dyv, {}, 1, c.m, c.n);
  const auto sdb = ref::matmul_abs(ones, dyv, 1, c.m, c.n);
  expect_matmul_close(db.download(), rdb, sdb);
}

TEST(MatmulKernels, OddShapesMatchReference) {
  const std::size_t dims[] = {1, 3, 17, 65, 130};
  std::uint32_t seed = 51;
  // Every dimension takes each odd size at least once, in a 5 × 5 Latin-square pattern.
  for (std::size_t i = 0; i < 5; ++i) {
    for (std::size_t j = 0; j < 5; ++j) check_case({dims[i], dims[j], dims[(i + j) % 5]}, seed++);
  }
}

// The shader's variants: one row per tile (M < 4: a linear layer on one
// input, the landmark net's fc 256 → 136), B through a vec4 view (N a
// multiple of 8; the forward and dW), both, and neither.
TEST(MatmulKernels, RowVectorsAndAlignedColumnsMatchReference) {
  const Case cases[] = {{1, 256, 136}, {2, 33, 16}, {3, 8, 8}, {5, 40, 24},
                        {1, 7, 9},     {4, 5, 32},  {9, 1, 8}};
  std::uint32_t seed = 54;
  for (const Case& c : cases) check_case(c, seed++);
}

TEST(MatmulKernels, LargeMatchesReference) {
  const auto t0 = std::chrono::steady_clock::now();
  check_case({256, 256, 256}, 52);
  check_case({64, 300, 129}, 53);
  const double s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  std::printf("[ matmul ] 256³ + 64·300·129 with backward and references: %.2f s\n", s);
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
