// One forward for inference and training: a conv asked for its consumer's
// input layout writes padded planes only where nothing needs a gradient, the
// consumer reads them with no padding pass, and the chain equals the plain
// one exactly (the same kernels on the same values).
#include <vkjr2/nets/layers.hpp>
#include <vkjr2/nets/ops.hpp>
#include <vkjr2/runtime/error.hpp>

#include <gtest/gtest.h>

#include <random>

#include "support/test_device.hpp"

namespace vkjr2::nets {
namespace {

namespace k = kernels;

Var random_var(const Device& d, const Shape& s, std::uint32_t seed, bool grad = false) {
  return Var(Tensor::from(d, s, test::random_floats(std::size_t(s.numel()), seed)), grad);
}

k::Conv2dParams same3x3(const Shape& x, int stride, k::Activation act) {
  k::Conv2dParams p;
  p.stride_y = p.stride_x = stride;
  p.pad = k::same_padding(x[2], x[3], 3, 3, stride, stride);
  p.activation = act;
  return p;
}

// a = conv_a(x) written in conv_b's input layout; y = conv_b(a) + a (the
// shortcut read from the same padded planes when conv_b is a stride-1
// 'same' conv), against the same chain with every activation plain.
TEST(ConvPlans, ChainsThroughTheConsumersPaddedInput) {
  const Device& d = test::device();
  std::mt19937 rng(17);
  auto uni = [&](int lo, int hi) { return std::uniform_int_distribution<int>(lo, hi)(rng); };
  int padded_runs = 0;
  for (int trial = 0; trial < 5; ++trial) {
    const Shape xs{uni(1, 2), uni(1, 6), uni(3, 20), uni(3, 24)};
    const std::int64_t c = uni(1, 3) * 4;
    const int stride = uni(1, 2);
    const bool depthwise_b = trial % 3 == 2;
    SCOPED_TRACE("trial " + std::to_string(trial) + ": x " + xs.str() + ", " + std::to_string(c) +
                 " channels, stride " + std::to_string(stride) +
                 (depthwise_b ? ", depthwise consumer" : ""));
    const Var x = random_var(d, xs, 100 + trial);
    const Var wa = random_var(d, {c, xs[1], 3, 3}, 200 + trial);
    const Var ba = random_var(d, {c}, 300 + trial);
    const k::Conv2dParams pa = same3x3(xs, stride, k::Activation::relu);
    const Shape as = k::conv2d_output_shape(xs, wa.shape(), pa);
    k::Conv2dParams pb = same3x3(as, 1, k::Activation::leaky_relu);
    if (depthwise_b) pb.groups = int(c);
    const Var wb = random_var(d, {c, depthwise_b ? 1 : c, 3, 3}, 400 + trial);
    const Var bb = random_var(d, {c}, 500 + trial);
    ConvPlans plans_a, plans_b;
    Stream s(d);
    Tape t(s, /*recording=*/false);
    const k::PlaneLayout lb = plans_b.input_layout(t, as, wb, bb, pb);
    const Var a = conv2d(t, x, wa, ba, pa, &plans_a, Var(), lb);
    EXPECT_EQ(a.padded(), !lb.plain());
    EXPECT_EQ(a.shape(), as);
    const Var y = conv2d(t, a, wb, bb, pb, &plans_b, a);
    const Var a_plain = conv2d(t, x, wa, ba, pa);
    const Var y_plain = conv2d(t, a_plain, wb, bb, pb, nullptr, a_plain);
    const Tensor a_copy = plain(t, a);
    s.run();
    EXPECT_FALSE(y.padded());
    EXPECT_EQ(a_copy.download(), a_plain.value().download());
    EXPECT_EQ(y.value().download(), y_plain.value().download());
    if (a.padded()) {
      ++padded_runs;
      EXPECT_THROW((void)a.value(), InvalidArgument);
      EXPECT_THROW(a.set_requires_grad(true), InvalidArgument);
    }
  }
  EXPECT_GE(padded_runs, 3);
}

// Where a gradient is needed the same calls keep every activation plain: the
// consumer's weights need one (its layout is plain), or the producer's
// output does (it ignores the layout it was given).
TEST(ConvPlans, ActivationsStayPlainWhereGradientsFlow) {
  const Device& d = test::device();
  const Shape xs{1, 4, 10, 12};
  const k::Conv2dParams p = same3x3(xs, 1, k::Activation::relu);
  Conv2d a(d, 4, 8, 3, 3, p, true, 1), b(d, 8, 8, 3, 3, p, true, 2);
  ConvPlans plans_b;
  Stream s(d);
  {
    Tape t(s);  // b's weights need a gradient: it reads plain input
    EXPECT_TRUE(plans_b.input_layout(t, {1, 8, 10, 12}, b.weight, b.bias, p).plain());
  }
  b.weight.set_requires_grad(false);
  b.bias.set_requires_grad(false);
  a.weight.set_requires_grad(false);
  a.bias.set_requires_grad(false);
  Tape t(s);
  const k::PlaneLayout lb = plans_b.input_layout(t, {1, 8, 10, 12}, b.weight, b.bias, p);
  ASSERT_FALSE(lb.plain());
  const Var x = random_var(d, xs, 7, /*grad=*/true);  // pixel gradients through frozen convs
  const Var h = conv2d(t, x, a.weight, a.bias, p, nullptr, Var(), lb);
  EXPECT_FALSE(h.padded());
  EXPECT_TRUE(h.requires_grad());
  const Var y = conv2d(t, h, b.weight, b.bias, p, &plans_b);
  t.backward(sum_all(t, y));
  s.run();
  EXPECT_TRUE(x.has_grad());
}

// A ReLU fused into the depthwise read (inference) and the composed ReLU +
// conv (a tape recording gradients) give the same output.
TEST(ConvPlans, InputReluFusedOrComposed) {
  const Device& d = test::device();
  const Shape xs{2, 8, 9, 13};
  k::Conv2dParams p = same3x3(xs, 1, k::Activation::none);
  p.groups = 8;
  p.relu_input = true;
  const Var w = random_var(d, {8, 1, 3, 3}, 3);
  const Var x = random_var(d, xs, 4);
  const Var xg = random_var(d, xs, 4, /*grad=*/true);
  Stream s(d);
  Tape infer(s, false), train(s);
  const Var fused = conv2d(infer, x, w, Var(), p);
  const Var composed = conv2d(train, xg, w, Var(), p);
  train.backward(sum_all(train, composed));
  s.run();
  EXPECT_EQ(fused.value().download(), composed.value().download());
  EXPECT_TRUE(xg.has_grad());
}

}  // namespace
}  // namespace vkjr2::nets
