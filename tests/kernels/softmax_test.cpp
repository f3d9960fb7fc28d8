#include <vkjr2/kernels/ref/softmax_ref.hpp>
#include <vkjr2/kernels/softmax.hpp>

#include <gtest/gtest.h>

#include <cmath>
#include <string>
#include <vector>

#include "support/gradcheck.hpp"
#include "support/op_check.hpp"
#include "support/test_device.hpp"

namespace vkjr2 {
namespace {

TEST(SoftmaxKernels, ForwardAndBackwardMatchReference) {
  const std::vector<Shape> edges = {{1, 1}, {3, 5}, {33, 10}, {2, 3, 1000}};
  test::check_op("softmax/log_softmax", {.seed = 41, .cases = 8}, [&](test::OpCase& c) {
    const Shape shape = c.edge_or(edges, [&]() -> Shape {
      return {c.uniform(1, 4), c.uniform(1, 40), c.uniform(1, 1500)};
    });
    c.describe("x " + shape.str());
    const auto k = std::size_t(shape[-1]);
    // Large offsets: the max subtraction keeps exp finite.
    const auto xv = c.floats(shape.numel(), 60.f, 90.f), dyv = c.floats(shape.numel());
    Tensor x = c.tensor(shape, xv), dy = c.tensor(shape, dyv);
    Tensor y = c.empty(shape), ly = c.empty(shape), dx = c.empty(shape), ldx = c.empty(shape);
    Stream s(c.device);
    kernels::softmax(s, x, y);
    kernels::log_softmax(s, x, ly);
    kernels::softmax_backward(s, y, dy, dx);
    kernels::log_softmax_backward(s, ly, dy, ldx);
    s.run();
    const auto ry = ref::softmax(xv, k, false), rly = ref::softmax(xv, k, true);
    c.expect("softmax", y, ry, {1e-4, 1e-7});
    c.expect("log_softmax", ly, rly, {1e-4, 1e-5});
    c.expect("softmax backward", dx, ref::softmax_backward(ry, dyv, k, false), {1e-4, 1e-6});
    c.expect("log_softmax backward", ldx, ref::softmax_backward(rly, dyv, k, true), {1e-4, 1e-5});
  });
}

TEST(SoftmaxKernels, GradientsMatchFiniteDifferences) {
  Device& dev = test::device();
  const Shape shape{4, 9};
  const std::uint32_t seed = 42;
  SCOPED_TRACE("seed " + std::to_string(seed));
  const auto xv = test::random_floats(36, seed, -2.f, 2.f), w = test::random_floats(36, seed + 1);
  Tensor x = Tensor::from(dev, shape, xv), wt = Tensor::from(dev, shape, w);
  for (bool log : {false, true}) {
    Tensor y = Tensor::empty(dev, shape), dx = Tensor::empty(dev, shape);
    Stream s(dev);
    if (log) {
      kernels::log_softmax(s, x, y);
      kernels::log_softmax_backward(s, y, wt, dx);
    } else {
      kernels::softmax(s, x, y);
      kernels::softmax_backward(s, y, wt, dx);
    }
    s.run();
    auto loss = [&](std::span<const float> xs) {
      Tensor xt = Tensor::from(dev, shape, xs), o = Tensor::empty(dev, shape);
      Stream st(dev);
      if (log) kernels::log_softmax(st, xt, o);
      if (!log) kernels::softmax(st, xt, o);
      st.run();
      return test::weighted_sum(o.download(), w);
    };
    test::expect_gradient_matches(loss, xv, dx.download(), log ? "log_softmax" : "softmax",
                                  {.step = 1e-2});
  }
}

TEST(SoftmaxKernels, BadInputsAreClearErrors) {
  Device& dev = test::device();
  Stream s(dev);
  Tensor a = Tensor::empty(dev, {4, 5}), b = Tensor::empty(dev, {5, 4});
  EXPECT_THROW(kernels::softmax(s, a, b), InvalidArgument);
  EXPECT_THROW(kernels::log_softmax_backward(s, a, a, b), InvalidArgument);
  EXPECT_THROW(kernels::softmax(s, Tensor::empty(dev, {0, 3}), Tensor::empty(dev, {0, 3})),
               InvalidArgument);
}

}  // namespace
}  // namespace vkjr2
