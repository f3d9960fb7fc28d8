#include <vkjr2/nets/layers.hpp>
#include <vkjr2/nets/optimizer.hpp>
#include <vkjr2/runtime/error.hpp>

#include <gtest/gtest.h>

#include <cmath>

#include "support/op_check.hpp"
#include "support/test_device.hpp"

namespace vkjr2::nets {
namespace {

// Flat index of an int index expression (test shapes are small).
std::size_t flat(std::int64_t i) { return static_cast<std::size_t>(i); }

TEST(NetsLayers, BatchNormTrainingMatchesReferenceAndUpdatesRunningStats) {
  const Device& d = test::device();
  const Shape s{3, 2, 4, 5};
  const std::vector<float> x = test::random_floats(std::size_t(s.numel()), 7, -2.f, 3.f);
  BatchNorm2d bn(d, 2, 0.1f, 1e-5f);
  bn.gamma.value().upload(std::vector<float>{1.5f, -0.5f});
  bn.beta.value().upload(std::vector<float>{0.25f, 1.f});
  Stream st(d);
  Tape t(st);
  const Var y = bn.forward(t, Var(Tensor::from(d, s, x)));
  st.run();

  const int m = 3 * 4 * 5;
  std::vector<float> want(x.size()), want_rm(2), want_rv(2);
  for (int c = 0; c < 2; ++c) {
    double mean = 0, var = 0;
    for (int n = 0; n < 3; ++n)
      for (int i = 0; i < 20; ++i) mean += x[flat((n * 2 + c) * 20 + i)];
    mean /= m;
    for (int n = 0; n < 3; ++n)
      for (int i = 0; i < 20; ++i) var += std::pow(x[flat((n * 2 + c) * 20 + i)] - mean, 2);
    var /= m;
    const double g = c == 0 ? 1.5 : -0.5, b = c == 0 ? 0.25 : 1.0;
    for (int n = 0; n < 3; ++n)
      for (int i = 0; i < 20; ++i) {
        const auto k = flat((n * 2 + c) * 20 + i);
        want[k] = float(g * (x[k] - mean) / std::sqrt(var + 1e-5) + b);
      }
    want_rm[std::size_t(c)] = float(0.1 * mean);
    want_rv[std::size_t(c)] = float(0.9 + 0.1 * var * m / (m - 1));
  }
  test::expect_all_close("y", y.value().download(), want, {1e-4, 1e-5});
  test::expect_all_close("bn.running_mean", bn.running_mean.value().download(), want_rm,
                         {1e-5, 1e-6});
  test::expect_all_close("bn.running_var", bn.running_var.value().download(), want_rv,
                         {1e-5, 1e-6});

  // Eval mode uses the running statistics.
  bn.eval();
  Tape t2(st, false);
  const Var z = bn.forward(t2, Var(Tensor::from(d, s, x)));
  st.run();
  const auto zv = z.value().download();
  for (std::size_t k = 0; k < x.size(); ++k) {
    const int c = int(k / 20) % 2;
    const double g = c == 0 ? 1.5 : -0.5, b = c == 0 ? 0.25 : 1.0;
    const double expect =
        g * (x[k] - want_rm[std::size_t(c)]) / std::sqrt(double(want_rv[std::size_t(c)]) + 1e-5) +
        b;
    ASSERT_NEAR(zv[k], expect, 1e-4) << k;
  }
}

TEST(NetsLayers, SameSeedSameWeightsAndBadSizesRejected) {
  const Device& d = test::device();
  kernels::Conv2dParams p;
  Conv2d a(d, 3, 4, 3, 3, p, true, 42), b(d, 3, 4, 3, 3, p, true, 42),
      c(d, 3, 4, 3, 3, p, true, 43);
  EXPECT_EQ(a.weight.value().download(), b.weight.value().download());
  EXPECT_NE(a.weight.value().download(), c.weight.value().download());
  EXPECT_EQ(a.named_parameters().size(), 2u);
  EXPECT_EQ(a.named_parameters()[0].first, "weight");
  p.groups = 2;
  EXPECT_THROW(Conv2d(d, 3, 4, 3, 3, p, true, 1), InvalidArgument);
  EXPECT_THROW(Linear(d, 0, 4, true, 1), InvalidArgument);
}

// The layer packs its weight once and reuses it; after an optimizer step (or
// set_value) the next forward must see the new weight, exactly as a conv that
// packs on every call.
TEST(NetsLayers, Conv2dPackedWeightFollowsOptimizerSteps) {
  const Device& d = test::device();
  kernels::Conv2dParams p;
  p.pad = kernels::same_padding(9, 11, 3, 3, 1, 1);
  p.activation = kernels::Activation::relu;
  Conv2d conv(d, 16, 8, 3, 3, p, true, 7);
  ASSERT_EQ(kernels::Conv2dPlan(d, Shape{1, 16, 9, 11}, conv.weight.shape(), p).algo(),
            kernels::Conv2dAlgo::blocked);
  Stream st(d);
  const Var x(Tensor::from(d, Shape{1, 16, 9, 11}, uniform_init(16 * 9 * 11, 1.f, 3)));
  const auto unpacked = [&] {  // packs on this call
    Tape t(st, false);
    const Var y = conv2d(t, x, conv.weight, conv.bias, p);
    st.run();
    return y.value().download();
  };
  const auto run_layer = [&] {
    Tape t(st, false);
    const Var y = conv.forward(t, x);
    st.run();
    return y.value().download();
  };
  std::vector<float> previous = run_layer();
  EXPECT_EQ(previous, unpacked());
  Sgd sgd(conv.named_parameters(), {0.5f});
  for (int step = 0; step < 2; ++step) {
    Tape t(st);
    t.backward(sum_all(t, conv.forward(t, x)));
    const std::uint64_t before = conv.weight.version();
    sgd.step(st);
    st.run();
    EXPECT_GT(conv.weight.version(), before);
    const auto after = run_layer();
    EXPECT_EQ(after, unpacked()) << "step " << step;
    EXPECT_NE(after, previous) << "step " << step << " did not change the output";
    previous = after;
  }
  conv.weight.set_value(Tensor::from(d, conv.weight.shape(),
                                     uniform_init(std::size_t(conv.weight.numel()), 0.1f, 9)));
  EXPECT_EQ(run_layer(), unpacked());
}

TEST(NetsOptimizer, WarmupCosineSchedule) {
  const WarmupCosine s{1.f, 0.1f, 4, 14};
  EXPECT_FLOAT_EQ(s.at(0), 0.25f);
  EXPECT_FLOAT_EQ(s.at(3), 1.f);
  EXPECT_FLOAT_EQ(s.at(4), 1.f);
  EXPECT_NEAR(s.at(9), 0.55f, 1e-6);
  EXPECT_FLOAT_EQ(s.at(14), 0.1f);
  EXPECT_FLOAT_EQ(s.at(1000), 0.1f);
}

TEST(NetsOptimizer, SgdAndAdamStepsSkipParametersWithoutGradient) {
  const Device& d = test::device();
  Linear l(d, 2, 2, true, 5);
  const auto before = l.bias.value().download();
  Stream st(d);
  Tape t(st);
  // Only the weight gets a gradient: the bias is not used.
  const Var x(Tensor::from(d, Shape{1, 2}, std::vector<float>{1.f, 2.f}));
  t.backward(sum_all(t, linear(t, x, l.weight, Var())));
  Adam adam(l.named_parameters(), {});
  adam.step(st);
  st.run();
  EXPECT_EQ(l.bias.value().download(), before);
  EXPECT_EQ(adam.steps(), 1u);
  EXPECT_EQ(adam.state().size(), 4u);
  EXPECT_THROW(Adam({}, {}), InvalidArgument);
}

}  // namespace
}  // namespace vkjr2::nets
