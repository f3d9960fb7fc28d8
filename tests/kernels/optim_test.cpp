#include <vkjr2/kernels/optim.hpp>
#include <vkjr2/kernels/ref/optim_ref.hpp>

#include <gtest/gtest.h>

#include <cmath>
#include <string>
#include <vector>

#include "support/test_device.hpp"

namespace vkjr2 {
namespace {

// Same float arithmetic on both sides: bit-close (1e-6 relative).
void expect_bit_close(const std::vector<float>& got, const std::vector<float>& want) {
  ASSERT_EQ(got.size(), want.size());
  for (std::size_t i = 0; i < got.size(); ++i) {
    ASSERT_NEAR(got[i], want[i], 1e-6 * std::fabs(want[i]) + 1e-12) << "at " << i;
  }
}

TEST(OptimKernels, SgdMatchesReferenceOverSteps) {
  Device& dev = test::device();
  const std::uint32_t seed = 71;
  for (std::int64_t n : {1, 1025, 5000}) {
    for (float wd : {0.f, 1e-2f}) {
      SCOPED_TRACE("n " + std::to_string(n) + " wd " + std::to_string(wd) + " seed " +
                   std::to_string(seed));
      auto p = test::random_floats(std::size_t(n), seed);
      std::vector<float> v(std::size_t(n), 0.f);
      Tensor pt = Tensor::from(dev, {n}, p), vt = Tensor::from(dev, {n}, v);
      const kernels::SgdOptions o{.lr = 0.05f, .momentum = 0.9f, .weight_decay = wd};
      for (std::uint32_t step = 1; step <= 5; ++step) {
        const auto g = test::random_floats(std::size_t(n), seed + step);
        Tensor gt = Tensor::from(dev, {n}, g);
        Stream s(dev);
        kernels::sgd_step(s, pt, gt, vt, o);
        s.run();
        ref::sgd_step(p, g, v, o);
        if (step == 1 || step == 5) {
          expect_bit_close(pt.download(), p);
          expect_bit_close(vt.download(), v);
        }
      }
    }
  }
}

TEST(OptimKernels, AdamAndAdamWMatchReferenceOverSteps) {
  Device& dev = test::device();
  const std::uint32_t seed = 72;
  for (bool decoupled : {false, true}) {
    for (std::int64_t n : {1, 1025, 5000}) {
      SCOPED_TRACE(std::string(decoupled ? "AdamW" : "Adam") + " n " + std::to_string(n) +
                   " seed " + std::to_string(seed));
      auto p = test::random_floats(std::size_t(n), seed);
      std::vector<float> m(std::size_t(n), 0.f), v(std::size_t(n), 0.f);
      Tensor pt = Tensor::from(dev, {n}, p), mt = Tensor::from(dev, {n}, m);
      Tensor vt = Tensor::from(dev, {n}, v);
      const kernels::AdamOptions o{.lr = 1e-2f, .weight_decay = 0.05f, .decoupled = decoupled};
      for (std::uint32_t step = 1; step <= 6; ++step) {
        const auto g = test::random_floats(std::size_t(n), seed + step);
        Tensor gt = Tensor::from(dev, {n}, g);
        Stream s(dev);
        kernels::adam_step(s, pt, gt, mt, vt, step, o);
        s.run();
        ref::adam_step(p, g, m, v, step, o);
        if (step == 1 || step == 6) {
          expect_bit_close(pt.download(), p);
          expect_bit_close(mt.download(), m);
          expect_bit_close(vt.download(), v);
        }
      }
    }
  }
}

// Adam's first step moves every parameter by about lr · sign(g) (m̂ / sqrt(v̂) = ±1).
TEST(OptimKernels, AdamFirstStepIsLrTimesSign) {
  Device& dev = test::device();
  const auto g = test::random_floats(100, 73);
  Tensor p = Tensor::from(dev, {100}, std::vector<float>(100, 0.f));
  Tensor m = Tensor::from(dev, {100}, std::vector<float>(100, 0.f));
  Tensor v = Tensor::from(dev, {100}, std::vector<float>(100, 0.f));
  Tensor gt = Tensor::from(dev, {100}, g);
  Stream s(dev);
  kernels::adam_step(s, p, gt, m, v, 1, {.lr = 1e-3f});
  s.run();
  const auto pv = p.download();
  for (std::size_t i = 0; i < 100; ++i) EXPECT_NEAR(pv[i], -1e-3f * (g[i] > 0 ? 1 : -1), 1e-7f);
}

TEST(OptimKernels, BadInputsAreClearErrors) {
  Device& dev = test::device();
  Stream s(dev);
  Tensor p = Tensor::empty(dev, {10}), g = Tensor::empty(dev, {11}), v = Tensor::empty(dev, {10});
  EXPECT_THROW(kernels::sgd_step(s, p, g, v, {}), InvalidArgument);
  EXPECT_THROW(kernels::sgd_step(s, p, v, g, {}), InvalidArgument);
  EXPECT_THROW(kernels::adam_step(s, p, v, v, g, 1, {}), InvalidArgument);
  try {
    kernels::adam_step(s, p, v, v, v, 0, {});
    FAIL();
  } catch (const InvalidArgument& e) {
    EXPECT_NE(std::string(e.what()).find("step"), std::string::npos) << e.what();
  }
}

}  // namespace
}  // namespace vkjr2
