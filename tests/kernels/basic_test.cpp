#include <vkjr2/kernels/basic.hpp>
#include <vkjr2/kernels/ref/basic_ref.hpp>

#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include "support/test_device.hpp"

namespace vkjr2 {
namespace {

// Sizes that do and do not divide the workgroup (256) and per-group (1024,
// 2048) counts, plus random ones.
std::vector<std::int64_t> sizes(std::uint32_t seed) {
  std::vector<std::int64_t> s = {1, 7, 255, 256, 1023, 1024, 1025, 2047, 2048, 2049, 65537};
  std::mt19937 rng(seed);
  for (int i = 0; i < 4; ++i)
    s.push_back(std::uniform_int_distribution<std::int64_t>(1, 3'000'000)(rng));
  return s;
}

TEST(BasicKernels, FillCopyAxpyMatchReference) {
  Device& dev = test::device();
  const std::uint32_t seed = 1234;
  for (std::int64_t n : sizes(seed)) {
    SCOPED_TRACE("n=" + std::to_string(n) + " seed=" + std::to_string(seed));
    const auto xs = test::random_floats(std::size_t(n), seed + std::uint32_t(n));
    const auto ys = test::random_floats(std::size_t(n), seed + 1 + std::uint32_t(n));
    Tensor x = Tensor::from(dev, {n}, xs);
    Tensor y = Tensor::from(dev, {n}, ys);
    Tensor c = Tensor::empty(dev, {n});
    Tensor f = Tensor::empty(dev, {n});
    Stream s(dev);
    kernels::fill(s, f, -3.5f);
    kernels::copy(s, x, c);
    kernels::axpy(s, 0.75f, x, y);
    s.run();
    std::vector<float> ry = ys;
    ref::axpy(0.75f, xs, ry);
    const auto gf = f.download(), gc = c.download(), gy = y.download();
    for (std::int64_t i = 0; i < n; ++i) {
      ASSERT_EQ(gf[i], -3.5f);
      ASSERT_EQ(gc[i], xs[i]);
      ASSERT_NEAR(gy[i], ry[i], 1e-6f * (1 + std::fabs(ry[i])));
    }
  }
}

TEST(BasicKernels, SumMatchesReference) {
  Device& dev = test::device();
  const std::uint32_t seed = 99;
  for (std::int64_t n : sizes(seed)) {
    SCOPED_TRACE("n=" + std::to_string(n) + " seed=" + std::to_string(seed));
    const auto xs = test::random_floats(std::size_t(n), seed + std::uint32_t(n));
    Tensor x = Tensor::from(dev, {n}, xs);
    Tensor out = Tensor::empty(dev, {1});
    Stream s(dev);
    kernels::sum(s, x, out);
    s.run();
    double abs_sum = 0;
    for (float v : xs) abs_sum += std::fabs(v);
    // fp32 tree sum: error bounded by ~log2(n)·eps·Σ|x|.
    EXPECT_NEAR(out.download()[0], ref::sum(xs),
                1e-4 * abs_sum / std::sqrt(double(n)) + 1e-5 * abs_sum);
  }
}

TEST(BasicKernels, SumIsDeterministic) {
  Device& dev = test::device();
  const auto xs = test::random_floats(1'000'003, 7);
  Tensor x = Tensor::from(dev, {1'000'003}, xs);
  Tensor a = Tensor::empty(dev, {1}), b = Tensor::empty(dev, {1});
  Stream s(dev);
  kernels::sum(s, x, a);
  kernels::sum(s, x, b);
  s.run();
  EXPECT_EQ(a.download()[0], b.download()[0]);
}

TEST(BasicKernels, BadInputsAreClearErrors) {
  Device& dev = test::device();
  Stream s(dev);
  Tensor a = Tensor::empty(dev, {10}), b = Tensor::empty(dev, {11});
  EXPECT_THROW(kernels::axpy(s, 1.f, a, b), InvalidArgument);
  EXPECT_THROW(kernels::copy(s, a, b), InvalidArgument);
  EXPECT_THROW(kernels::sum(s, a, b), InvalidArgument);
  Tensor empty = Tensor::empty(dev, {0});
  try {
    kernels::fill(s, empty, 1.f);
    FAIL();
  } catch (const InvalidArgument& e) {
    EXPECT_NE(std::string(e.what()).find("empty"), std::string::npos) << e.what();
  }
  Tensor ints = Tensor::empty(dev, {10}, DType::i32);
  EXPECT_THROW(kernels::fill(s, ints, 1.f), InvalidArgument);
}

TEST(BasicKernels, GroupsFoldIntoYBeyondTheXLimit) {
  DeviceInfo info;
  info.max_workgroup_count = {65535, 65535, 65535};
  const Groups small = groups_1d(100, info);
  EXPECT_EQ(small.x, 100u);
  EXPECT_EQ(small.y, 1u);
  const Groups big = groups_1d(200'000, info);
  EXPECT_LE(big.x, 65535u);
  EXPECT_GE(std::uint64_t(big.x) * big.y, 200'000u);
}

TEST(BasicKernels, NaNPropagates) {
  Device& dev = test::device();
  Tensor x = Tensor::from(dev, {4}, std::vector<float>{1, NAN, 2, 3});
  Tensor out = Tensor::empty(dev, {1});
  Stream s(dev);
  kernels::sum(s, x, out);
  s.run();
  EXPECT_TRUE(std::isnan(out.download()[0]));
}

}  // namespace
}  // namespace vkjr2
