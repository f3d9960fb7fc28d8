#include <vkjr2/kernels/ref/softmax_ref.hpp>
#include <vkjr2/kernels/softmax.hpp>

#include <gtest/gtest.h>

#include <cmath>
#include <string>
#include <vector>

#include "support/expect.hpp"
#include "support/gradcheck.hpp"
#include "support/test_device.hpp"

namespace vkjr2 {
namespace {

void expect_close(const std::vector<float>& got, const std::vector<float>& want, double rtol = 1e-4,
                  double atol = 1e-6) {
  test::expect_all_near(got, want, rtol, atol);
}

TEST(SoftmaxKernels, ForwardAndBackwardMatchReference) {
  Device& dev = test::device();
  const std::uint32_t seed = 41;
  for (const Shape& shape : {Shape{1, 1}, Shape{3, 5}, Shape{33, 10}, Shape{2, 3, 1000}}) {
    SCOPED_TRACE("shape " + shape.str() + " seed " + std::to_string(seed));
    const auto n = std::size_t(shape.numel()), k = std::size_t(shape[-1]);
    // Large offsets: the max subtraction keeps exp finite.
    const auto xv = test::random_floats(n, seed, 60.f, 90.f);
    const auto dyv = test::random_floats(n, seed + 1);
    Tensor x = Tensor::from(dev, shape, xv), dy = Tensor::from(dev, shape, dyv);
    Tensor y = Tensor::empty(dev, shape), ly = Tensor::empty(dev, shape);
    Tensor dx = Tensor::empty(dev, shape), ldx = Tensor::empty(dev, shape);
    Stream s(dev);
    kernels::softmax(s, x, y);
    kernels::log_softmax(s, x, ly);
    kernels::softmax_backward(s, y, dy, dx);
    kernels::log_softmax_backward(s, ly, dy, ldx);
    s.run();
    const auto ry = ref::softmax(xv, k, false), rly = ref::softmax(xv, k, true);
    expect_close(y.download(), ry, 1e-4, 1e-7);
    expect_close(ly.download(), rly, 1e-4, 1e-5);
    expect_close(dx.download(), ref::softmax_backward(ry, dyv, k, false), 1e-4, 1e-6);
    expect_close(ldx.download(), ref::softmax_backward(rly, dyv, k, true), 1e-4, 1e-5);
  }
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
