#include <vkjr2/kernels/layout.hpp>
#include <vkjr2/kernels/ref/layout_ref.hpp>

#include <gtest/gtest.h>

#include <array>
#include <cmath>
#include <string>
#include <vector>

#include "support/expect_error.hpp"
#include "support/gradcheck.hpp"
#include "support/op_check.hpp"
#include "support/test_device.hpp"

namespace vkjr2 {
namespace {

using kernels::Pad2d;
using kernels::SliceStart;
using ref::Nchw;

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
    c.expect("y", y, ref::pad(xv, s, p, -2.5f), test::kExact);
    // pad's adjoint is the crop of its interior.
    c.expect("dx", dx, ref::slice(dyv, o, SliceStart{0, p.top, p.left}, s), test::kExact);
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
    c.expect("y", y, ref::slice(xv, s, at, o), test::kExact);
    // slice's adjoint: dy placed at `at`, zero elsewhere.
    std::vector<float> want(std::size_t(s.numel()), 0.f);
    std::size_t k = 0;
    for (std::int64_t n = 0; n < o.n; ++n)
      for (std::int64_t ch = 0; ch < o.c; ++ch)
        for (std::int64_t i = 0; i < o.h; ++i)
          for (std::int64_t j = 0; j < o.w; ++j)
            want[std::size_t(((n * s.c + ch + at.channel) * s.h + i + at.row) * s.w + j + at.col)] =
                dyv[k++];
    c.expect("dx", dx, want, test::kExact);
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
    c.expect("y", y, ref::concat_channels(values, parts), test::kExact);
    for (std::size_t k = 0; k < parts.size(); ++k) {
      c.expect("dx" + std::to_string(k), dxs[k], values[k], test::kExact);
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
    c.expect("dx", dx, rdx, test::kExact);
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

TEST(LayoutKernels, PixelShuffleMatchesReference) {
  // [N, C, H, W, r] of the small side: r = 1 (a copy), one pixel, widths past
  // the 256-column group, NAFNet's r = 2; the quad variant (W a multiple of
  // 4, r <= 4) at r = 1..4 and past a 64-lane group, r = 5 on such a width
  // (the scalar one); then random ones, half of them on quad widths.
  using Dims = std::array<int, 5>;
  const std::vector<Dims> edges = {{1, 3, 4, 5, 1},  {1, 1, 1, 1, 2},  {2, 2, 3, 130, 2},
                                   {1, 16, 8, 8, 2}, {1, 2, 5, 3, 3},  {1, 2, 4, 8, 1},
                                   {2, 3, 5, 8, 2},  {1, 2, 3, 12, 3}, {1, 1, 2, 4, 4},
                                   {1, 1, 2, 8, 5},  {1, 2, 9, 132, 2}};
  test::check_op("pixel_shuffle/unshuffle", {.seed = 705, .cases = 19}, [&](test::OpCase& c) {
    const Dims k =
        c.index < int(edges.size())
            ? edges[std::size_t(c.index)]
            : Dims{c.uniform(1, 3), c.uniform(1, 6), c.uniform(1, 24),
                   c.uniform(0, 1) != 0 ? 4 * c.uniform(1, 6) : c.uniform(1, 24), c.uniform(1, 4)};
    const int r = k[4];
    const Nchw small{k[0], k[1] * r * r, k[2], k[3]};
    const Nchw big{k[0], k[1], k[2] * r, k[3] * r};
    c.describe("x " + shape(small).str() + " r " + std::to_string(r));
    const auto xv = c.floats(small.numel()), bv = c.floats(big.numel());
    Tensor x = c.tensor(shape(small), xv), y = c.empty(shape(big));
    Tensor b = c.tensor(shape(big), bv), u = c.empty(shape(small));
    Stream st(c.device);
    kernels::pixel_shuffle(st, x, r, y);
    kernels::pixel_unshuffle(st, b, r, u);
    st.run();
    c.expect("shuffle", y, ref::pixel_shuffle(xv, small, r), test::kExact);
    c.expect("unshuffle", u, ref::pixel_unshuffle(bv, small, r), test::kExact);
    // Each undoes the other.
    EXPECT_EQ(ref::pixel_unshuffle(ref::pixel_shuffle(xv, small, r), small, r), xv);
  });
}

TEST(LayoutKernels, FlipSpatialMatchesReference) {
  // A 3×3 weight (the conv backward's use), one pixel, rows past a 256 group.
  const std::vector<Shape> edges = {{4, 1, 3, 3}, {1, 1, 1, 1}, {2, 3, 17, 20}, {1, 2, 1, 300}};
  test::check_op("flip_spatial", {.seed = 706, .cases = 7}, [&](test::OpCase& c) {
    const Shape s = c.edge_or(edges, [&] { return c.nchw(3, 8, 30, 30); });
    c.describe("x " + s.str());
    const auto xv = c.floats(s.numel());
    Tensor x = c.tensor(s, xv), y = c.empty(s), back = c.empty(s);
    Stream st(c.device);
    kernels::flip_spatial(st, x, y);
    kernels::flip_spatial(st, y, back);
    st.run();
    c.expect("y", y, ref::flip_spatial(xv, {s[0], s[1], s[2], s[3]}), test::kExact);
    c.expect("flipped twice", back, xv, test::kExact);
  });
  Device& dev = test::device();
  Stream st(dev);
  test::expect_invalid_argument(
      [&] {
        kernels::flip_spatial(st, Tensor::empty(dev, {1, 1, 3, 3}),
                              Tensor::empty(dev, {1, 1, 3, 4}));
      },
      "y");
}

// PyTorch's order: channel c·r² + i·r + j lands at row offset i, column offset j.
TEST(LayoutKernels, PixelShuffleKnownValues) {
  Device& dev = test::device();
  Tensor x = Tensor::from(dev, {1, 4, 1, 2}, std::vector<float>{0, 1, 2, 3, 4, 5, 6, 7});
  Tensor y = Tensor::empty(dev, {1, 1, 2, 4});
  Stream st(dev);
  kernels::pixel_shuffle(st, x, 2, y);
  st.run();
  EXPECT_EQ(y.download(), (std::vector<float>{0, 2, 1, 3, 4, 6, 5, 7}));
}

// The backward of each is the other: L = Σ w ⊙ shuffle(x) has dL/dx = unshuffle(w).
TEST(LayoutKernels, PixelShuffleGradientsMatchFiniteDifferences) {
  Device& dev = test::device();
  const int r = 2;
  const Nchw small{2, 8, 3, 4}, big{2, 2, 6, 8};
  const std::uint32_t seed = 706;
  SCOPED_TRACE("seed=" + std::to_string(seed));
  const auto xv = test::random_floats(std::size_t(small.numel()), seed);
  const auto w = test::random_floats(std::size_t(big.numel()), seed + 1);
  const auto bv = test::random_floats(std::size_t(big.numel()), seed + 2);
  const auto ws = test::random_floats(std::size_t(small.numel()), seed + 3);
  Tensor wt = Tensor::from(dev, shape(big), w), wst = Tensor::from(dev, shape(small), ws);
  Tensor dx = Tensor::empty(dev, shape(small)), db = Tensor::empty(dev, shape(big));
  {
    Stream st(dev);
    kernels::pixel_unshuffle(st, wt, r, dx);  // backward of the shuffle
    kernels::pixel_shuffle(st, wst, r, db);   // backward of the unshuffle
    st.run();
  }
  auto loss = [&](bool unshuffle, std::span<const float> v) {
    const Nchw in = unshuffle ? big : small, out = unshuffle ? small : big;
    Tensor a = Tensor::from(dev, shape(in), v), y = Tensor::empty(dev, shape(out));
    Stream st(dev);
    if (unshuffle) {
      kernels::pixel_unshuffle(st, a, r, y);
    } else {
      kernels::pixel_shuffle(st, a, r, y);
    }
    st.run();
    return test::weighted_sum(y.download(), unshuffle ? ws : w);
  };
  test::expect_gradient_matches([&](std::span<const float> v) { return loss(false, v); }, xv,
                                dx.download(), "pixel_shuffle");
  test::expect_gradient_matches([&](std::span<const float> v) { return loss(true, v); }, bv,
                                db.download(), "pixel_unshuffle");
}

TEST(LayoutKernels, PixelShuffleBadInputsAreClearErrors) {
  Device& dev = test::device();
  Stream st(dev);
  Tensor x = Tensor::empty(dev, {1, 8, 3, 3}), y = Tensor::empty(dev, {1, 2, 6, 6});
  test::expect_invalid_argument([&] { kernels::pixel_shuffle(st, x, 0, y); }, "factor");
  Tensor x6 = Tensor::empty(dev, {1, 6, 3, 3});
  test::expect_invalid_argument([&] { kernels::pixel_shuffle(st, x6, 2, y); }, "multiple of r");
  Tensor y_bad = Tensor::empty(dev, {1, 2, 6, 5});
  test::expect_invalid_argument([&] { kernels::pixel_shuffle(st, x, 2, y_bad); }, "y");
  test::expect_invalid_argument([&] { kernels::pixel_unshuffle(st, y_bad, 2, x); }, "x");
  Tensor flat = Tensor::empty(dev, {8, 9});
  test::expect_invalid_argument([&] { kernels::pixel_shuffle(st, flat, 2, y); }, "rank");
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
