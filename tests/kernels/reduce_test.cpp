#include <vkjr2/kernels/reduce.hpp>
#include <vkjr2/kernels/ref/elementwise_ref.hpp>
#include <vkjr2/kernels/ref/reduce_ref.hpp>

#include <gtest/gtest.h>

#include <cmath>
#include <string>
#include <vector>

#include "support/gradcheck.hpp"
#include "support/op_check.hpp"
#include "support/test_device.hpp"

namespace vkjr2 {
namespace {

// rows × k: single rows, short rows (< subgroup), rows not filling a group,
// long rows; then random ones.
const std::vector<Shape> kRowEdges = {{1, 1},    {1, 7},    {3, 5}, {33, 17},
                                      {70, 130}, {2, 5000}, {1, 65}};

TEST(ReduceKernels, RowReductionsMatchReference) {
  test::check_op("row reductions", {.seed = 31, .cases = 11}, [](test::OpCase& c) {
    const Shape shape = c.edge_or(kRowEdges, [&]() -> Shape {
      return {c.uniform(1, 80), c.uniform(1, 3000)};
    });
    const std::int64_t rows = shape[0], k = shape[1];
    c.describe("[rows, k] " + shape.str());
    const auto xv = c.floats(rows * k);
    Tensor x = c.tensor(shape, xv);
    Tensor o[3] = {c.empty({rows}), c.empty({rows, 1}), c.empty({rows})};
    Tensor mv = c.empty({rows}), mi = c.empty({rows}, DType::i32);
    Stream s(c.device);
    kernels::sum_rows(s, x, o[0]);
    kernels::mean_rows(s, x, o[1]);
    kernels::l2norm_rows(s, x, o[2]);
    kernels::max_rows(s, x, mv, mi);
    s.run();
    const char* names[3] = {"sum_rows", "mean_rows", "l2norm_rows"};
    for (int op = 0; op < 3; ++op) {
      // Sums: the rounding grows with Σ|x| (≤ k).
      c.expect(names[op], o[op], ref::reduce_rows(op, xv, std::size_t(k)),
               {1e-4, 1e-6 * double(k)});
    }
    std::vector<float> rv;
    std::vector<std::int32_t> ri;
    ref::max_rows(xv, std::size_t(k), rv, ri);
    c.expect("max_rows value", mv, rv, test::kExact);
    c.expect_equal("max_rows index", mi, ri);
  });
}

TEST(ReduceKernels, FullReductionsAndMaxAll) {
  const std::vector<Shape> edges = {{1}, {7}, {4096}, {4097}, {100'003}};
  test::check_op("sum_all/mean_all/max_all", {.seed = 32, .cases = 8}, [&](test::OpCase& c) {
    const Shape shape = c.edge_or(edges, [&]() -> Shape { return {c.uniform(1, 300'000)}; });
    const std::int64_t n = shape[0];
    c.describe("n " + std::to_string(n));
    auto xv = c.floats(n);
    if (n > 10) xv[std::size_t(n) - 3] = 5.f;  // the max near the end, twice
    if (n > 10) xv[std::size_t(n) / 2] = 5.f;
    Tensor x = c.tensor(shape, xv);
    Tensor sm = c.empty({1}), mn = c.empty({1}), mv = c.empty({1}), mi = c.empty({1}, DType::i32);
    Stream s(c.device);
    kernels::sum_all(s, x, sm);
    kernels::mean_all(s, x, mn);
    kernels::max_all(s, x, mv, mi);
    s.run();
    double total = 0;
    for (float v : xv) total += v;
    c.expect("sum_all", sm, {float(total)}, {0, 1e-5 * double(n)});
    c.expect("mean_all", mn, {float(total / double(n))}, {0, 1e-5});
    std::vector<float> rv;
    std::vector<std::int32_t> ri;
    ref::max_rows(xv, xv.size(), rv, ri);
    c.expect("max_all value", mv, rv, test::kExact);
    c.expect_equal("max_all index", mi, ri);
  });
}

TEST(ReduceKernels, MaxTiesNaNAndInfinity) {
  Device& dev = test::device();
  Tensor x = Tensor::from(dev, {3, 4},
                          std::vector<float>{2, 1, 2, 0,                                  //
                                             -INFINITY, -INFINITY, -INFINITY, -INFINITY,  //
                                             1, NAN, 3, NAN});
  Tensor v = Tensor::empty(dev, {3}), i = Tensor::empty(dev, {3}, DType::i32);
  Stream s(dev);
  kernels::max_rows(s, x, v, i);
  s.run();
  const auto vv = v.download();
  std::vector<std::int32_t> iv(3);
  i.download_bytes(iv.data(), 12);
  EXPECT_EQ(vv[0], 2.f);
  EXPECT_EQ(iv[0], 0);
  EXPECT_EQ(vv[1], -INFINITY);
  EXPECT_EQ(iv[1], 0);
  EXPECT_TRUE(std::isnan(vv[2]));
  EXPECT_EQ(iv[2], 1);
}

TEST(ReduceKernels, ChannelSumsMatchReference) {
  const std::vector<Shape> edges = {{5},          {3, 7},        {64, 100},
                                    {2, 3, 1, 1}, {2, 5, 17, 9}, {3, 40, 4, 4}};
  test::check_op("sum_channels", {.seed = 33, .cases = 10}, [&](test::OpCase& c) {
    const Shape shape = c.edge_or(edges, [&] { return c.nchw(4, 70, 40, 40); });
    c.describe("x " + shape.str());
    const auto n = std::size_t(shape.numel());
    const auto ch = std::uint32_t(shape.rank() == 1 ? shape[0] : shape[1]);
    const auto hw = std::uint32_t(shape.rank() == 1 ? 1 : n / std::size_t(shape[0]) / ch);
    const auto xv = c.floats(shape.numel());
    Tensor x = c.tensor(shape, xv), out = c.empty({ch});
    Stream s(c.device);
    kernels::sum_channels(s, x, out);
    s.run();
    c.expect("sum_channels", out, ref::channel_sum(xv, {}, ch, hw), {1e-4, 1e-5});
  });
}

TEST(ReduceKernels, GradientsMatchFiniteDifferences) {
  Device& dev = test::device();
  const std::int64_t rows = 5, k = 13;
  const std::uint32_t seed = 34;
  SCOPED_TRACE("seed " + std::to_string(seed));
  const auto xv = test::random_floats(std::size_t(rows * k), seed);
  const auto w = test::random_floats(std::size_t(rows), seed + 1);
  Tensor x = Tensor::from(dev, {rows, k}, xv), wt = Tensor::from(dev, {rows}, w);
  Tensor y = Tensor::empty(dev, {rows}), dx = Tensor::empty(dev, {rows, k});
  using Fwd = void (*)(Stream&, const Tensor&, const Tensor&);
  const Fwd fwd[3] = {kernels::sum_rows, kernels::mean_rows, kernels::l2norm_rows};
  for (int op = 0; op < 3; ++op) {
    Stream s(dev);
    if (op == 0) kernels::sum_rows_backward(s, wt, dx);
    if (op == 1) kernels::mean_rows_backward(s, wt, dx);
    if (op == 2) {
      kernels::l2norm_rows(s, x, y);
      kernels::l2norm_rows_backward(s, x, y, wt, dx);
    }
    s.run();
    auto loss = [&](std::span<const float> xs) {
      Tensor xt = Tensor::from(dev, {rows, k}, xs), o = Tensor::empty(dev, {rows});
      Stream st(dev);
      fwd[op](st, xt, o);
      st.run();
      return test::weighted_sum(o.download(), w);
    };
    test::expect_gradient_matches(loss, xv, dx.download(), "row reduction " + std::to_string(op));
  }
  // Full reductions: L = w0 · sum(x) / mean(x).
  Tensor w0 = Tensor::from(dev, {1}, std::vector<float>{0.7f});
  for (int op = 0; op < 2; ++op) {
    Stream s(dev);
    if (op == 0) kernels::sum_all_backward(s, w0, dx);
    if (op == 1) kernels::mean_all_backward(s, w0, dx);
    s.run();
    auto loss = [&](std::span<const float> xs) {
      Tensor xt = Tensor::from(dev, {rows, k}, xs), o = Tensor::empty(dev, {1});
      Stream st(dev);
      if (op == 0) kernels::sum_all(st, xt, o);
      if (op == 1) kernels::mean_all(st, xt, o);
      st.run();
      return 0.7 * o.download()[0];
    };
    test::expect_gradient_matches(loss, xv, dx.download(), "full reduction " + std::to_string(op));
  }
}

TEST(ReduceKernels, BadInputsAreClearErrors) {
  Device& dev = test::device();
  Stream s(dev);
  Tensor x = Tensor::empty(dev, {4, 5}), r3 = Tensor::empty(dev, {3});
  Tensor i4 = Tensor::empty(dev, {4}, DType::i32), f4 = Tensor::empty(dev, {4});
  try {
    kernels::sum_rows(s, x, r3);
    FAIL();
  } catch (const InvalidArgument& e) {
    EXPECT_NE(std::string(e.what()).find("one per row"), std::string::npos) << e.what();
  }
  EXPECT_THROW(kernels::max_rows(s, x, f4, f4), InvalidArgument);
  EXPECT_THROW(kernels::max_all(s, x, f4, i4), InvalidArgument);
  EXPECT_THROW(kernels::mean_all(s, Tensor::empty(dev, {0}), f4), InvalidArgument);
  EXPECT_THROW(kernels::sum_channels(s, x, f4), InvalidArgument);
  EXPECT_THROW(kernels::l2norm_rows_backward(s, x, f4, f4, f4), InvalidArgument);
}

}  // namespace
}  // namespace vkjr2
