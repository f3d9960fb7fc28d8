#include <vkjr2/kernels/layout.hpp>
#include <vkjr2/kernels/ref/layout_ref.hpp>

#include <gtest/gtest.h>

#include <cmath>
#include <string>
#include <vector>

#include "support/gradcheck.hpp"
#include "support/op_check.hpp"
#include "support/test_device.hpp"

namespace vkjr2 {
namespace {

using kernels::Pad2d;
using kernels::SliceStart;
using ref::Nchw;

constexpr test::Tol kExact{0, 0};

Shape shape(Nchw s) { return Shape{s.n, s.c, s.h, s.w}; }

// Edge shapes (one element, odd sizes, 16×16, a 67-wide row), then random ones.
const std::vector<Shape> kEdges = {{1, 1, 1, 1}, {2, 3, 7, 9}, {1, 4, 16, 16}, {3, 2, 5, 67}};
constexpr int kRandomCases = 4;

Nchw draw_shape(test::OpCase& c, const std::vector<Shape>& edges = kEdges) {
  const Shape s = c.edge_or(edges, [&] { return c.nchw(3, 6, 30, 30); });
  return {s[0], s[1], s[2], s[3]};
}

TEST(LayoutKernels, PadMatchesReference) {
  const int cases = int(kEdges.size()) + kRandomCases;
  test::check_op("pad", {.seed = 701, .cases = cases}, [](test::OpCase& c) {
    const Nchw s = draw_shape(c);
    const Pad2d p{c.uniform(0, 3), c.uniform(0, 3), c.uniform(0, 5), c.uniform(0, 2)};
    c.describe("x " + shape(s).str() + " pad " + std::to_string(p.top) + "/" +
               std::to_string(p.bottom) + "/" + std::to_string(p.left) + "/" +
               std::to_string(p.right));
    const Nchw o{s.n, s.c, s.h + p.top + p.bottom, s.w + p.left + p.right};
    const auto xv = c.floats(s.numel()), dyv = c.floats(o.numel());
    Tensor x = c.tensor(shape(s), xv), y = c.empty(shape(o));
    Tensor dy = c.tensor(shape(o), dyv), dx = c.empty(shape(s));
    Stream st(c.device);
    kernels::pad(st, x, p, -2.5f, y);
    kernels::pad_backward(st, dy, p, dx);
    st.run();
    c.expect("y", y, ref::pad(xv, s, p, -2.5f), kExact);
    // pad's adjoint is the crop of its interior.
    c.expect("dx", dx, ref::slice(dyv, o, SliceStart{0, p.top, p.left}, s), kExact);
  });
}

TEST(LayoutKernels, SliceMatchesReference) {
  const int cases = int(kEdges.size()) + kRandomCases;
  test::check_op("slice", {.seed = 702, .cases = cases}, [](test::OpCase& c) {
    const Nchw s = draw_shape(c);
    auto uni = [&](std::int64_t lo, std::int64_t hi) {
      return std::int64_t(c.uniform(int(lo), int(hi)));
    };
    const Nchw o{s.n, uni(1, s.c), uni(1, s.h), uni(1, s.w)};
    const SliceStart at{uni(0, s.c - o.c), uni(0, s.h - o.h), uni(0, s.w - o.w)};
    c.describe("x " + shape(s).str() + " -> " + shape(o).str() + " at " +
               std::to_string(at.channel) + "," + std::to_string(at.row) + "," +
               std::to_string(at.col));
    const auto xv = c.floats(s.numel()), dyv = c.floats(o.numel());
    Tensor x = c.tensor(shape(s), xv), y = c.empty(shape(o));
    Tensor dy = c.tensor(shape(o), dyv), dx = c.empty(shape(s));
    Stream st(c.device);
    kernels::slice(st, x, at, y);
    kernels::slice_backward(st, dy, at, dx);
    st.run();
    c.expect("y", y, ref::slice(xv, s, at, o), kExact);
    // slice's adjoint: dy placed at `at`, zero elsewhere.
    std::vector<float> want(std::size_t(s.numel()), 0.f);
    std::size_t k = 0;
    for (std::int64_t n = 0; n < o.n; ++n)
      for (std::int64_t ch = 0; ch < o.c; ++ch)
        for (std::int64_t i = 0; i < o.h; ++i)
          for (std::int64_t j = 0; j < o.w; ++j)
            want[std::size_t(((n * s.c + ch + at.channel) * s.h + i + at.row) * s.w + j + at.col)] =
                dyv[k++];
    c.expect("dx", dx, want, kExact);
  });
}

TEST(LayoutKernels, ConcatMatchesReference) {
  std::vector<Shape> edges = kEdges;
  edges.push_back({17, 2, 3, 5});  // past kMaxCopies: the shader path instead of transfer copies
  const int cases = int(edges.size()) + kRandomCases;
  test::check_op("concat_channels", {.seed = 703, .cases = cases}, [&](test::OpCase& c) {
    const Nchw s = draw_shape(c, edges);
    const std::vector<Nchw> parts = {{s.n, s.c, s.h, s.w}, {s.n, 1, s.h, s.w}, {s.n, 3, s.h, s.w}};
    c.describe("parts " + shape(parts[0]).str() + ", " + shape(parts[1]).str() + ", " +
               shape(parts[2]).str());
    std::vector<std::vector<float>> values;
    std::vector<Tensor> xs, dxs;
    std::int64_t channels = 0;
    for (const Nchw& part : parts) {
      values.push_back(c.floats(part.numel()));
      xs.push_back(c.tensor(shape(part), values.back()));
      dxs.push_back(c.empty(shape(part)));
      channels += part.c;
    }
    Tensor y = c.empty({s.n, channels, s.h, s.w});
    Stream st(c.device);
    kernels::concat_channels(st, xs, y);
    kernels::concat_channels_backward(st, y, dxs);
    st.run();
    c.expect("y", y, ref::concat_channels(values, parts), kExact);
    for (std::size_t k = 0; k < parts.size(); ++k) {
      c.expect("dx" + std::to_string(k), dxs[k], values[k], kExact);
    }
  });
}

TEST(LayoutKernels, ChannelAffineMatchesReference) {
  const int cases = int(kEdges.size()) + kRandomCases;
  test::check_op("channel_affine", {.seed = 704, .cases = cases}, [](test::OpCase& c) {
    const Nchw s = draw_shape(c);
    c.describe("x " + shape(s).str());
    const auto xv = c.floats(s.numel()), dyv = c.floats(s.numel());
    const auto sv = c.floats(s.c, 0.5f, 2.f), bv = c.floats(s.c);
    Tensor x = c.tensor(shape(s), xv), y = c.empty(shape(s));
    Tensor scale = c.tensor({s.c}, sv), bias = c.tensor({s.c}, bv);
    Tensor dy = c.tensor(shape(s), dyv), dx = c.empty(shape(s));
    Tensor ds = c.empty({s.c}), db = c.empty({s.c});
    Stream st(c.device);
    kernels::channel_affine(st, x, scale, bias, y);
    kernels::channel_affine_backward(st, x, scale, dy, &dx, &ds, &db);
    st.run();
    c.expect("y", y, ref::channel_affine(xv, s, sv, bv), {0, 1e-6});
    std::vector<float> rdx, rds, rdb;
    ref::channel_affine_backward(xv, s, sv, dyv, rdx, rds, rdb);
    c.expect("dx", dx, rdx, kExact);
    const double tol = 1e-5 * double(s.n * s.h * s.w);  // fp32 sums of O(1) terms
    c.expect("dscale", ds, rds, {0, tol});
    c.expect("dbias", db, rdb, {0, tol});
  });
}

TEST(LayoutKernels, ChannelAffineGradientsMatchFiniteDifferences) {
  Device& dev = test::device();
  const std::uint32_t seed = 705;
  SCOPED_TRACE("seed=" + std::to_string(seed));
  const Nchw s{2, 3, 5, 4};
  const auto xv = test::random_floats(std::size_t(s.numel()), seed);
  const auto wv = test::random_floats(std::size_t(s.numel()), seed + 1);
  const auto sv = test::random_floats(3, seed + 2, 0.5f, 2.f);
  const auto bv = test::random_floats(3, seed + 3);
  Tensor x = Tensor::from(dev, shape(s), xv), w = Tensor::from(dev, shape(s), wv);
  Tensor scale = Tensor::from(dev, {3}, sv);
  Tensor dx = Tensor::empty(dev, shape(s)), ds = Tensor::empty(dev, {3}),
         db = Tensor::empty(dev, {3});
  Stream st(dev);
  kernels::channel_affine_backward(st, x, scale, w, &dx, &ds, &db);
  st.run();
  auto loss = [&](std::span<const float> xi, std::span<const float> si, std::span<const float> bi) {
    Tensor a = Tensor::from(dev, shape(s), xi), y = Tensor::empty(dev, shape(s));
    Tensor sc = Tensor::from(dev, {3}, si), bs = Tensor::from(dev, {3}, bi);
    Stream t(dev);
    kernels::channel_affine(t, a, sc, bs, y);
    t.run();
    return test::weighted_sum(y.download(), wv);
  };
  test::expect_gradient_matches([&](std::span<const float> xi) { return loss(xi, sv, bv); }, xv,
                                dx.download(), "dx");
  test::expect_gradient_matches([&](std::span<const float> si) { return loss(xv, si, bv); }, sv,
                                ds.download(), "dscale");
  test::expect_gradient_matches([&](std::span<const float> bi) { return loss(xv, sv, bi); }, bv,
                                db.download(), "dbias");
}

TEST(LayoutKernels, BadInputsAreClearErrors) {
  Device& dev = test::device();
  Stream st(dev);
  Tensor x = Tensor::empty(dev, {1, 2, 4, 4});
  Tensor y = Tensor::empty(dev, {1, 2, 5, 5});
  EXPECT_THROW(kernels::pad(st, x, Pad2d{1, 1, 1, 1}, 0.f, y), InvalidArgument);  // wants 6x6
  EXPECT_THROW(kernels::pad(st, x, Pad2d{-1, 2, 0, 1}, 0.f, y), InvalidArgument);
  EXPECT_THROW(kernels::slice(st, x, SliceStart{0, 0, 0}, y), InvalidArgument);  // larger
  Tensor small = Tensor::empty(dev, {1, 1, 2, 2});
  EXPECT_THROW(kernels::slice(st, x, SliceStart{1, 3, 0}, small), InvalidArgument);
  std::vector<Tensor> parts = {x, small};
  Tensor cat = Tensor::empty(dev, {1, 3, 4, 4});
  EXPECT_THROW(kernels::concat_channels(st, parts, cat), InvalidArgument);  // H, W differ
  EXPECT_THROW(kernels::concat_channels(st, std::span<const Tensor>{}, cat), InvalidArgument);
  Tensor scale3 = Tensor::empty(dev, {3});
  EXPECT_THROW(kernels::channel_affine(st, x, scale3, scale3, x), InvalidArgument);
  try {
    Tensor empty = Tensor::empty(dev, {0, 2, 4, 4});
    kernels::pad(st, empty, Pad2d{}, 0.f, empty);
    FAIL();
  } catch (const InvalidArgument& e) {
    EXPECT_NE(std::string(e.what()).find("empty"), std::string::npos) << e.what();
  }
}

}  // namespace
}  // namespace vkjr2
