#include <vkjr2/kernels/activation.hpp>
#include <vkjr2/kernels/ref/elementwise_ref.hpp>

#include <gtest/gtest.h>

#include <cmath>
#include <string>
#include <vector>

#include "support/gradcheck.hpp"
#include "support/op_check.hpp"
#include "support/test_device.hpp"

namespace vkjr2 {
namespace {

// Edge shapes first (one element, one past a workgroup), then random ones.
Shape draw_shape(test::OpCase& c) {
  if (c.index == 0) return {1};
  if (c.index == 1) return {1025};
  return {c.uniform(1, 3), c.uniform(1, 6), c.uniform(1, 40), c.uniform(1, 40)};
}

TEST(ActivationKernels, ForwardAndBackwardMatchReference) {
  test::check_op("activations", {.seed = 21}, [](test::OpCase& c) {
    const Shape shape = draw_shape(c);
    c.describe("x " + shape.str());
    const auto xv = c.floats(shape.numel(), -4.f, 4.f), dyv = c.floats(shape.numel());
    Tensor x = c.tensor(shape, xv), dy = c.tensor(shape, dyv);
    std::vector<Tensor> t;
    for (int i = 0; i < 8; ++i) t.push_back(c.empty(shape));
    Stream s(c.device);
    kernels::relu(s, x, t[0]);
    kernels::relu_backward(s, x, dy, t[1]);
    kernels::leaky_relu(s, x, 0.1f, t[2]);
    kernels::leaky_relu_backward(s, x, 0.1f, dy, t[3]);
    kernels::sigmoid(s, x, t[4]);
    kernels::sigmoid_backward(s, t[4], dy, t[5]);
    kernels::tanh_activation(s, x, t[6]);
    kernels::tanh_activation_backward(s, t[6], dy, t[7]);
    s.run();
    using ref::Unary;
    c.expect("relu", t[0], ref::unary(Unary::relu, xv));
    c.expect("relu backward", t[1], ref::unary_backward(Unary::relu, xv, dyv));
    c.expect("leaky_relu", t[2], ref::unary(Unary::leaky_relu, xv, 0.1f));
    c.expect("leaky_relu backward", t[3], ref::unary_backward(Unary::leaky_relu, xv, dyv, 0.1f));
    const auto sy = ref::unary(Unary::sigmoid, xv), ty = ref::unary(Unary::tanh, xv);
    c.expect("sigmoid", t[4], sy);
    c.expect("sigmoid backward", t[5], ref::unary_backward(Unary::sigmoid, sy, dyv), {1e-4, 1e-6});
    c.expect("tanh", t[6], ty);
    c.expect("tanh backward", t[7], ref::unary_backward(Unary::tanh, ty, dyv), {1e-4, 1e-6});
  });
}

TEST(ActivationKernels, PreluMatchesReference) {
  test::check_op("prelu", {.seed = 22, .cases = 6}, [](test::OpCase& c) {
    const Shape shape =
        c.index == 0 ? Shape{3, 7}
                     : Shape{c.uniform(1, 3), c.uniform(1, 6), c.uniform(1, 20), c.uniform(1, 20)};
    c.describe("x " + shape.str());
    const auto n = std::size_t(shape.numel());
    const auto ch = std::uint32_t(shape[1]);
    const std::uint32_t hw = std::uint32_t(n / std::size_t(shape[0]) / ch);
    const auto xv = c.floats(shape.numel()), dyv = c.floats(shape.numel());
    const auto sv = c.floats(ch, 0.f, 0.5f);
    Tensor x = c.tensor(shape, xv), dy = c.tensor(shape, dyv);
    Tensor sl = c.tensor({ch}, sv), y = c.empty(shape);
    Tensor dx = c.empty(shape), ds = c.empty({ch});
    Stream s(c.device);
    kernels::prelu(s, x, sl, y);
    kernels::prelu_backward(s, x, sl, dy, &dx, &ds);
    s.run();
    std::vector<float> rdx, rds;
    ref::prelu_backward(xv, sv, dyv, ch, hw, rdx, rds);
    c.expect("prelu", y, ref::prelu(xv, sv, ch, hw));
    c.expect("prelu dx", dx, rdx);
    c.expect("prelu dslope", ds, rds, {1e-4, 1e-5});
  });
}

TEST(ActivationKernels, GradientsMatchFiniteDifferences) {
  Device& dev = test::device();
  const Shape shape{2, 3, 4, 5};
  const std::uint32_t seed = 23;
  SCOPED_TRACE("seed " + std::to_string(seed));
  const auto n = std::size_t(shape.numel());
  // Away from the kink at 0 so central differences are exact for ReLU-likes.
  auto xv = test::random_floats(n, seed, 0.05f, 2.f);
  for (std::size_t i = 0; i < n; i += 2) xv[i] = -xv[i];
  const auto w = test::random_floats(n, seed + 1), sv = test::random_floats(3, seed + 2, 0.f, .5f);
  Tensor x = Tensor::from(dev, shape, xv), wt = Tensor::from(dev, shape, w);
  Tensor sl = Tensor::from(dev, {3}, sv);
  using Fwd = void (*)(Stream&, const Tensor&, const Tensor&);
  auto check = [&](const char* name, auto forward, auto backward_into) {
    Tensor dx = Tensor::empty(dev, shape);
    {
      Stream s(dev);
      backward_into(s, dx);
      s.run();
    }
    auto loss = [&](std::span<const float> xs) {
      Tensor xt = Tensor::from(dev, shape, xs), y = Tensor::empty(dev, shape);
      Stream s(dev);
      forward(s, xt, y);
      s.run();
      return test::weighted_sum(y.download(), w);
    };
    test::expect_gradient_matches(loss, xv, dx.download(), name, {.step = 1e-2});
  };
  Tensor y = Tensor::empty(dev, shape);
  check("relu", Fwd(kernels::relu),
        [&](Stream& s, const Tensor& dx) { kernels::relu_backward(s, x, wt, dx); });
  check(
      "leaky_relu",
      [](Stream& s, const Tensor& a, const Tensor& o) { kernels::leaky_relu(s, a, 0.2f, o); },
      [&](Stream& s, const Tensor& dx) { kernels::leaky_relu_backward(s, x, 0.2f, wt, dx); });
  check(
      "prelu", [&](Stream& s, const Tensor& a, const Tensor& o) { kernels::prelu(s, a, sl, o); },
      [&](Stream& s, const Tensor& dx) { kernels::prelu_backward(s, x, sl, wt, &dx, nullptr); });
  check("sigmoid", Fwd(kernels::sigmoid), [&](Stream& s, const Tensor& dx) {
    kernels::sigmoid(s, x, y);
    kernels::sigmoid_backward(s, y, wt, dx);
  });
  check("tanh", Fwd(kernels::tanh_activation), [&](Stream& s, const Tensor& dx) {
    kernels::tanh_activation(s, x, y);
    kernels::tanh_activation_backward(s, y, wt, dx);
  });
  // PReLU slope gradient.
  Tensor ds = Tensor::empty(dev, {3});
  {
    Stream s(dev);
    kernels::prelu_backward(s, x, sl, wt, nullptr, &ds);
    s.run();
  }
  auto loss_slope = [&](std::span<const float> ss) {
    Tensor st = Tensor::from(dev, {3}, ss), o = Tensor::empty(dev, shape);
    Stream s(dev);
    kernels::prelu(s, x, st, o);
    s.run();
    return test::weighted_sum(o.download(), w);
  };
  test::expect_gradient_matches(loss_slope, sv, ds.download(), "prelu slope");
}

TEST(ActivationKernels, NaNPropagatesAndLargeInputsSaturate) {
  Device& dev = test::device();
  Tensor x = Tensor::from(dev, {4}, std::vector<float>{NAN, 100.f, -100.f, 0.f});
  Tensor r = Tensor::empty(dev, {4}), sg = Tensor::empty(dev, {4}), th = Tensor::empty(dev, {4});
  Stream s(dev);
  kernels::relu(s, x, r);
  kernels::sigmoid(s, x, sg);
  kernels::tanh_activation(s, x, th);
  s.run();
  const auto rv = r.download(), sv = sg.download(), tv = th.download();
  EXPECT_TRUE(std::isnan(rv[0]) && std::isnan(sv[0]) && std::isnan(tv[0]));
  EXPECT_EQ(sv[1], 1.f);
  EXPECT_EQ(sv[2], 0.f);
  EXPECT_EQ(tv[1], 1.f);
  EXPECT_EQ(tv[2], -1.f);
  EXPECT_EQ(tv[3], 0.f);
}

TEST(ActivationKernels, BadInputsAreClearErrors) {
  Device& dev = test::device();
  Stream s(dev);
  Tensor a = Tensor::empty(dev, {2, 3, 4, 4}), b = Tensor::empty(dev, {2, 3, 4, 5});
  Tensor s4 = Tensor::empty(dev, {4}), empty = Tensor::empty(dev, {0});
  EXPECT_THROW(kernels::relu(s, a, b), InvalidArgument);
  EXPECT_THROW(kernels::sigmoid_backward(s, a, b, a), InvalidArgument);
  EXPECT_THROW(kernels::prelu(s, a, s4, a), InvalidArgument);
  EXPECT_THROW(kernels::prelu_backward(s, a, s4, a, nullptr, &s4), InvalidArgument);
  try {
    kernels::tanh_activation(s, empty, empty);
    FAIL();
  } catch (const InvalidArgument& e) {
    EXPECT_NE(std::string(e.what()).find("empty"), std::string::npos) << e.what();
  }
}

}  // namespace
}  // namespace vkjr2
