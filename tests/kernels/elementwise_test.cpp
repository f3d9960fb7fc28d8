#include <vkjr2/kernels/elementwise.hpp>
#include <vkjr2/kernels/ref/elementwise_ref.hpp>

#include <gtest/gtest.h>

#include <cmath>
#include <string>
#include <vector>

#include "support/expect_error.hpp"
#include "support/gradcheck.hpp"
#include "support/op_check.hpp"
#include "support/test_device.hpp"

namespace vkjr2 {
namespace {

// Edge shapes: odd, not dividing the 1024-element group, 1×1 images, rank
// 1..4; multiples of 4 (the vec4 binary path) with a partial last group
// (4092, 4100) and exact groups (2×4096). Then random ones.
const std::vector<Shape> kEdges = {
    {1}, {7}, {3, 5}, {2, 3, 1, 1}, {2, 5, 17, 9}, {1, 4, 33, 31}, {1025}, {4100}, {2, 4096}};
constexpr int kCases = 13;  // the edges and 4 random shapes

Shape draw_shape(test::OpCase& c) {
  return c.edge_or(kEdges, [&] { return c.nchw(3, 6, 40, 40); });
}

TEST(ElementwiseKernels, BinaryMatchReference) {
  test::check_op("add/sub/mul", {.seed = 11, .cases = kCases}, [](test::OpCase& c) {
    const Shape shape = draw_shape(c);
    c.describe("a, b " + shape.str());
    const auto av = c.floats(shape.numel()), bv = c.floats(shape.numel());
    Tensor a = c.tensor(shape, av), b = c.tensor(shape, bv);
    Tensor o[3] = {c.empty(shape), c.empty(shape), c.empty(shape)};
    Stream s(c.device);
    kernels::add(s, a, b, o[0]);
    kernels::sub(s, a, b, o[1]);
    kernels::mul(s, a, b, o[2]);
    s.run();
    const char* names[3] = {"add", "sub", "mul"};
    for (int op = 0; op < 3; ++op) c.expect(names[op], o[op], ref::binary(op, av, bv));
  });
}

// A sub-tensor view at a 16-byte offset (the vec4 path binds it as RGBA
// texels), each op against the reference.
TEST(ElementwiseKernels, BinaryOnViewsMatchReference) {
  test::check_op("add/sub/mul on views", {.seed = 12, .cases = 4}, [](test::OpCase& c) {
    const std::int64_t n = 4 * c.uniform(1, 1024) + c.uniform(0, 3);
    const std::int64_t offset = 4 * c.uniform(1, 2);  // views start 16-byte aligned
    c.describe("n " + std::to_string(n) + " at offset " + std::to_string(offset));
    const auto av = c.floats(n + 8), bv = c.floats(n + 8);
    Tensor a = c.tensor({n + 8}, av), b = c.tensor({n + 8}, bv);
    const Tensor va = a.view({n}, offset), vb = b.view({n}, offset);
    Tensor o = c.empty({n + 8});
    const Tensor vo = o.view({n}, offset);
    const std::vector<float> sa(av.begin() + offset, av.begin() + offset + n),
        sb(bv.begin() + offset, bv.begin() + offset + n);
    const char* names[3] = {"add", "sub", "mul"};
    for (int op = 0; op < 3; ++op) {
      Stream s(c.device);
      if (op == 0) kernels::add(s, va, vb, vo);
      if (op == 1) kernels::sub(s, va, vb, vo);
      if (op == 2) kernels::mul(s, va, vb, vo);
      s.run();
      c.expect(names[op], vo.download(), ref::binary(op, sa, sb));
    }
  });
}

TEST(ElementwiseKernels, ChannelBroadcastMatchesReference) {
  test::check_op("add_channel/mul_channel", {.seed = 12, .cases = kCases}, [](test::OpCase& c) {
    const Shape shape = draw_shape(c);
    c.describe("x " + shape.str());
    const auto n = std::size_t(shape.numel());
    const std::uint32_t ch = shape.rank() == 1 ? std::uint32_t(shape[0]) : std::uint32_t(shape[1]);
    const std::uint32_t hw = shape.rank() <= 2 ? 1u : std::uint32_t(n / shape[0] / ch);
    const auto xv = c.floats(shape.numel()), vv = c.floats(ch), dyv = c.floats(shape.numel());
    Tensor x = c.tensor(shape, xv), v = c.tensor({ch}, vv), dy = c.tensor(shape, dyv);
    Tensor ya = c.empty(shape), ym = c.empty(shape), dx = c.empty(shape);
    Tensor dva = c.empty({ch}), dvm = c.empty({ch});
    Stream s(c.device);
    kernels::add_channel(s, x, v, ya);
    kernels::mul_channel(s, x, v, ym);
    kernels::add_channel_backward(s, dy, dva);
    kernels::mul_channel_backward(s, x, v, dy, &dx, &dvm);
    s.run();
    c.expect("add_channel", ya, ref::binary(0, xv, vv, ch, hw));
    c.expect("mul_channel", ym, ref::binary(2, xv, vv, ch, hw));
    c.expect("mul_channel dx", dx, ref::binary(2, dyv, vv, ch, hw));
    c.expect("add_channel dv", dva, ref::channel_sum(dyv, {}, ch, hw), {1e-4, 1e-5});
    c.expect("mul_channel dv", dvm, ref::channel_sum(dyv, xv, ch, hw), {1e-4, 1e-5});
  });
}

// The gate's x: [N, 2C, spatial...] of rank 2..4, the half past one and
// several 256-element groups, a batch (the halves are per sample).
const std::vector<Shape> kGateEdges = {{1, 2},       {3, 4},        {2, 6, 7},
                                       {1, 2, 1, 1}, {2, 8, 9, 31}, {3, 32, 16, 17}};

TEST(ElementwiseKernels, SimpleGateMatchesReference) {
  test::check_op(
      "simple_gate", {.seed = 15, .cases = int(kGateEdges.size()) + 4}, [](test::OpCase& c) {
        const Shape s = c.edge_or(kGateEdges, [&] {
          const Shape r = c.nchw(4, 16, 40, 40);
          return Shape{r[0], 2 * r[1], r[2], r[3]};
        });
        c.describe("x " + s.str());
        const auto batch = std::uint32_t(s[0]), ch = std::uint32_t(s[1] / 2);
        const auto hw = std::uint32_t(s.numel() / s[0] / s[1]);
        std::vector<std::int64_t> hd(s.dims().begin(), s.dims().end());
        hd[1] /= 2;
        const Shape h(hd);
        const auto xv = c.floats(s.numel()), dyv = c.floats(h.numel());
        Tensor x = c.tensor(s, xv), dy = c.tensor(h, dyv);
        Tensor y = c.empty(h), dx = c.empty(s);
        Stream st(c.device);
        kernels::simple_gate(st, x, y);
        kernels::simple_gate_backward(st, x, dy, dx);
        st.run();
        c.expect("y", y, ref::simple_gate(xv, batch, ch, hw), test::kExact);
        c.expect("dx", dx, ref::simple_gate_backward(xv, dyv, batch, ch, hw), test::kExact);
      });
}

TEST(ElementwiseKernels, SimpleGateGradientMatchesFiniteDifferences) {
  Device& dev = test::device();
  const Shape s{2, 6, 3, 4}, h{2, 3, 3, 4};
  const std::uint32_t seed = 16;
  SCOPED_TRACE("seed " + std::to_string(seed));
  const auto xv = test::random_floats(std::size_t(s.numel()), seed);
  const auto w = test::random_floats(std::size_t(h.numel()), seed + 1);
  Tensor x = Tensor::from(dev, s, xv), wt = Tensor::from(dev, h, w), dx = Tensor::empty(dev, s);
  Stream st(dev);
  kernels::simple_gate_backward(st, x, wt, dx);
  st.run();
  auto loss = [&](std::span<const float> xs) {
    Tensor xt = Tensor::from(dev, s, xs), y = Tensor::empty(dev, h);
    Stream s2(dev);
    kernels::simple_gate(s2, xt, y);
    s2.run();
    return test::weighted_sum(y.download(), w);
  };
  test::expect_gradient_matches(loss, xv, dx.download(), "simple_gate dx");
}

TEST(ElementwiseKernels, UnaryMatchReference) {
  test::check_op("scale_shift/exp/log", {.seed = 13, .cases = kCases}, [](test::OpCase& c) {
    const Shape shape = draw_shape(c);
    c.describe("x " + shape.str());
    const auto xv = c.floats(shape.numel(), 0.1f, 3.f);  // log needs x > 0
    const auto dyv = c.floats(shape.numel());
    Tensor x = c.tensor(shape, xv), dy = c.tensor(shape, dyv);
    std::vector<Tensor> t;
    for (int i = 0; i < 6; ++i) t.push_back(c.empty(shape));
    Stream s(c.device);
    kernels::scale_shift(s, x, -1.5f, 0.25f, t[0]);
    kernels::scale_shift_backward(s, dy, -1.5f, t[1]);
    kernels::exponential(s, x, t[2]);
    kernels::exponential_backward(s, t[2], dy, t[3]);
    kernels::logarithm(s, x, t[4]);
    kernels::logarithm_backward(s, x, dy, t[5]);
    s.run();
    using ref::Unary;
    c.expect("scale_shift", t[0], ref::unary(Unary::scale_shift, xv, -1.5f, 0.25f));
    c.expect("scale_shift backward", t[1], ref::unary_backward(Unary::scale_shift, xv, dyv, -1.5f));
    const auto ey = ref::unary(Unary::exp, xv);
    c.expect("exp", t[2], ey);
    c.expect("exp backward", t[3], ref::unary_backward(Unary::exp, ey, dyv));
    c.expect("log", t[4], ref::unary(Unary::log, xv));
    c.expect("log backward", t[5], ref::unary_backward(Unary::log, xv, dyv));
  });
}

// L = Σ w ⊙ f(x) on the device; analytic dL/dx from the backward kernel fed w.
TEST(ElementwiseKernels, GradientsMatchFiniteDifferences) {
  Device& dev = test::device();
  const Shape shape{2, 3, 5, 4};
  const std::uint32_t seed = 14;
  SCOPED_TRACE("seed " + std::to_string(seed));
  const auto n = std::size_t(shape.numel());
  const auto xv = test::random_floats(n, seed, 0.5f, 2.f), bv = test::random_floats(n, seed + 1);
  const auto vv = test::random_floats(3, seed + 2), w = test::random_floats(n, seed + 3);
  Tensor b = Tensor::from(dev, shape, bv), v = Tensor::from(dev, {3}, vv);
  Tensor wt = Tensor::from(dev, shape, w);
  auto loss_of = [&](auto&& forward) {
    return [&, forward](std::span<const float> xs) {
      Tensor x = Tensor::from(dev, shape, xs), y = Tensor::empty(dev, shape);
      Stream s(dev);
      forward(s, x, y);
      s.run();
      return test::weighted_sum(y.download(), w);
    };
  };
  Tensor x = Tensor::from(dev, shape, xv), y = Tensor::empty(dev, shape);
  Tensor dx = Tensor::empty(dev, shape), dv = Tensor::empty(dev, {3});
  {  // mul w.r.t. a
    Stream s(dev);
    kernels::mul_backward(s, x, b, wt, &dx, nullptr);
    s.run();
    test::expect_gradient_matches(
        loss_of([&](Stream& st, const Tensor& a, const Tensor& o) { kernels::mul(st, a, b, o); }),
        xv, dx.download(), "mul");
  }
  {  // mul_channel w.r.t. x and v
    Stream s(dev);
    kernels::mul_channel_backward(s, x, v, wt, &dx, &dv);
    s.run();
    test::expect_gradient_matches(loss_of([&](Stream& st, const Tensor& a, const Tensor& o) {
                                    kernels::mul_channel(st, a, v, o);
                                  }),
                                  xv, dx.download(), "mul_channel dx");
    auto loss_v = [&](std::span<const float> vs) {
      Tensor vt = Tensor::from(dev, {3}, vs), o = Tensor::empty(dev, shape);
      Stream st(dev);
      kernels::mul_channel(st, x, vt, o);
      st.run();
      return test::weighted_sum(o.download(), w);
    };
    test::expect_gradient_matches(loss_v, vv, dv.download(), "mul_channel dv");
  }
  {  // exp (from the output) and log (from the input)
    Stream s(dev);
    kernels::exponential(s, x, y);
    kernels::exponential_backward(s, y, wt, dx);
    s.run();
    test::expect_gradient_matches(loss_of([](Stream& st, const Tensor& a, const Tensor& o) {
                                    kernels::exponential(st, a, o);
                                  }),
                                  xv, dx.download(), "exp", {.step = 1e-3});
    Stream s2(dev);
    kernels::logarithm_backward(s2, x, wt, dx);
    s2.run();
    test::expect_gradient_matches(
        loss_of([](Stream& st, const Tensor& a, const Tensor& o) { kernels::logarithm(st, a, o); }),
        xv, dx.download(), "log", {.step = 1e-3});
  }
}

TEST(ElementwiseKernels, SimpleGateBadInputsAreClearErrors) {
  Device& dev = test::device();
  Stream s(dev);
  Tensor odd = Tensor::empty(dev, {1, 3, 4, 4}), y = Tensor::empty(dev, {1, 1, 4, 4});
  test::expect_invalid_argument([&] { kernels::simple_gate(s, odd, y); }, "even");
  Tensor x = Tensor::empty(dev, {1, 4, 4, 4}), y_bad = Tensor::empty(dev, {1, 4, 4, 4});
  test::expect_invalid_argument([&] { kernels::simple_gate(s, x, y_bad); }, "y");
  Tensor vec = Tensor::empty(dev, {4});
  test::expect_invalid_argument([&] { kernels::simple_gate(s, vec, y); }, "rank 2 to 4");
  Tensor dy = Tensor::empty(dev, {1, 2, 4, 4});
  test::expect_invalid_argument(
      [&] {
        kernels::simple_gate_backward(s, x, dy, y_bad.view({1, 4, 4, 3}));
      },
      "dx");
}

TEST(ElementwiseKernels, BadInputsAreClearErrors) {
  Device& dev = test::device();
  Stream s(dev);
  Tensor a = Tensor::empty(dev, {2, 3, 4, 4}), b = Tensor::empty(dev, {2, 3, 4, 5});
  Tensor v4 = Tensor::empty(dev, {4}), empty = Tensor::empty(dev, {0});
  EXPECT_THROW(kernels::add(s, a, b, a), InvalidArgument);
  EXPECT_THROW(kernels::mul(s, a, a, b), InvalidArgument);
  try {
    kernels::add_channel(s, a, v4, a);
    FAIL();
  } catch (const InvalidArgument& e) {
    EXPECT_NE(std::string(e.what()).find("per channel"), std::string::npos) << e.what();
  }
  EXPECT_THROW(kernels::exponential(s, empty, empty), InvalidArgument);
  EXPECT_THROW(kernels::logarithm_backward(s, a, b, a), InvalidArgument);
  Tensor ints = Tensor::empty(dev, {2, 3, 4, 4}, DType::i32);
  EXPECT_THROW(kernels::scale_shift(s, ints, 1.f, 0.f, a), InvalidArgument);
}

}  // namespace
}  // namespace vkjr2
