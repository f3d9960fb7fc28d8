#include <vkjr2/nets/ops.hpp>
#include <vkjr2/runtime/error.hpp>

#include <gtest/gtest.h>

#include "support/test_device.hpp"

namespace vkjr2::nets {
namespace {

Var leaf(const std::vector<float>& v, bool grad = true) {
  return Var(Tensor::from(test::device(), Shape{std::int64_t(v.size())}, v), grad);
}

TEST(NetsAutograd, VarUsedTwiceReceivesTheSumOfItsGradients) {
  Stream s(test::device());
  Tape t(s);
  const Var x = leaf({1.f, -2.f, 3.f});
  // L = Σ x·x + Σ 3x  →  dL/dx = 2x + 3.
  const Var loss = add(t, sum_all(t, mul(t, x, x)), sum_all(t, scale_shift(t, x, 3.f)));
  t.backward(loss);
  s.run();
  EXPECT_EQ(x.grad().download(), (std::vector<float>{5.f, -1.f, 9.f}));
  EXPECT_EQ(t.size(), 0u) << "backward drops the recorded steps";
}

TEST(NetsAutograd, GradientsAccumulateAcrossBackwardsUntilZeroGrad) {
  Stream s(test::device());
  Tape t(s);
  const Var x = leaf({1.f, 2.f});
  for (int i = 0; i < 2; ++i) t.backward(sum_all(t, scale_shift(t, x, 2.f)));
  s.run();
  EXPECT_EQ(x.grad().download(), (std::vector<float>{4.f, 4.f}));
  x.zero_grad();
  EXPECT_FALSE(x.has_grad());
}

TEST(NetsAutograd, InferenceTapeRecordsNothing) {
  Stream s(test::device());
  Tape t(s, false);
  const Var x = leaf({1.f, 2.f});
  const Var y = sum_all(t, relu(t, x));
  EXPECT_FALSE(y.requires_grad());
  EXPECT_EQ(t.size(), 0u);
  s.run();
  EXPECT_EQ(y.value().download(), (std::vector<float>{3.f}));
  EXPECT_THROW(t.backward(y), InvalidArgument);
}

TEST(NetsAutograd, OnlyInputsNeedingGradientsGetThem) {
  Stream s(test::device());
  Tape t(s);
  const Var a = leaf({1.f, 2.f}, true);
  const Var b = leaf({3.f, 4.f}, false);
  t.backward(sum_all(t, mul(t, a, b)));
  s.run();
  EXPECT_EQ(a.grad().download(), (std::vector<float>{3.f, 4.f}));
  EXPECT_FALSE(b.has_grad());
}

TEST(NetsAutograd, BranchesNotReachingTheLossAreSkipped) {
  Stream s(test::device());
  Tape t(s);
  const Var x = leaf({1.f, 2.f});
  const Var unused = exp(t, x);  // recorded, but no gradient reaches it
  t.backward(sum_all(t, x));
  s.run();
  EXPECT_EQ(x.grad().download(), (std::vector<float>{1.f, 1.f}));
  EXPECT_FALSE(unused.has_grad());
}

TEST(NetsAutograd, BackwardRejectsNonScalarLoss) {
  Stream s(test::device());
  Tape t(s);
  const Var x = leaf({1.f, 2.f});
  try {
    t.backward(relu(t, x));
    FAIL() << "expected InvalidArgument";
  } catch (const InvalidArgument& e) {
    EXPECT_NE(std::string(e.what()).find("one element"), std::string::npos) << e.what();
  }
}

}  // namespace
}  // namespace vkjr2::nets
