#include <vkjr2/kernels/layout.hpp>
#include <vkjr2/kernels/ref/layout_ref.hpp>

#include <gtest/gtest.h>

#include <cmath>
#include <random>
#include <string>

#include "support/gradcheck.hpp"
#include "support/test_device.hpp"

namespace vkjr2 {
namespace {

using kernels::Pad2d;
using kernels::SliceStart;
using ref::Nchw;

Shape shape(Nchw s) { return Shape{s.n, s.c, s.h, s.w}; }
std::string str(Nchw s) { return shape(s).str(); }

std::vector<Nchw> shapes(std::uint32_t seed) {
  std::vector<Nchw> v = {{1, 1, 1, 1}, {2, 3, 7, 9}, {1, 4, 16, 16}, {3, 2, 5, 67}};
  std::mt19937 rng(seed);
  auto uni = [&](int lo, int hi) {
    return std::int64_t(std::uniform_int_distribution<int>(lo, hi)(rng));
  };
  for (int i = 0; i < 4; ++i) v.push_back({uni(1, 3), uni(1, 6), uni(1, 30), uni(1, 30)});
  return v;
}

TEST(LayoutKernels, PadMatchesReference) {
  Device& dev = test::device();
  const std::uint32_t seed = 701;
  std::mt19937 rng(seed);
  auto uni = [&](int lo, int hi) { return std::uniform_int_distribution<int>(lo, hi)(rng); };
  for (Nchw s : shapes(seed)) {
    const Pad2d p{uni(0, 3), uni(0, 3), uni(0, 5), uni(0, 2)};
    SCOPED_TRACE(str(s) + " pad " + std::to_string(p.top) + "/" + std::to_string(p.bottom) + "/" +
                 std::to_string(p.left) + "/" + std::to_string(p.right) +
                 " seed=" + std::to_string(seed));
    const Nchw o{s.n, s.c, s.h + p.top + p.bottom, s.w + p.left + p.right};
    const auto xv = test::random_floats(std::size_t(s.numel()), seed);
    const auto dyv = test::random_floats(std::size_t(o.numel()), seed + 1);
    Tensor x = Tensor::from(dev, shape(s), xv), y = Tensor::empty(dev, shape(o));
    Tensor dy = Tensor::from(dev, shape(o), dyv), dx = Tensor::empty(dev, shape(s));
    Stream st(dev);
    kernels::pad(st, x, p, -2.5f, y);
    kernels::pad_backward(st, dy, p, dx);
    st.run();
    EXPECT_EQ(y.download(), ref::pad(xv, s, p, -2.5f));
    // pad's adjoint is the crop of its interior.
    EXPECT_EQ(dx.download(), ref::slice(dyv, o, SliceStart{0, p.top, p.left}, s));
  }
}

TEST(LayoutKernels, SliceMatchesReference) {
  Device& dev = test::device();
  const std::uint32_t seed = 702;
  std::mt19937 rng(seed);
  auto uni = [&](std::int64_t lo, std::int64_t hi) {
    return std::uniform_int_distribution<std::int64_t>(lo, hi)(rng);
  };
  for (Nchw s : shapes(seed)) {
    const Nchw o{s.n, uni(1, s.c), uni(1, s.h), uni(1, s.w)};
    const SliceStart at{uni(0, s.c - o.c), uni(0, s.h - o.h), uni(0, s.w - o.w)};
    SCOPED_TRACE(str(s) + " -> " + str(o) + " at " + std::to_string(at.channel) + "," +
                 std::to_string(at.row) + "," + std::to_string(at.col) +
                 " seed=" + std::to_string(seed));
    const auto xv = test::random_floats(std::size_t(s.numel()), seed);
    const auto dyv = test::random_floats(std::size_t(o.numel()), seed + 1);
    Tensor x = Tensor::from(dev, shape(s), xv), y = Tensor::empty(dev, shape(o));
    Tensor dy = Tensor::from(dev, shape(o), dyv), dx = Tensor::empty(dev, shape(s));
    Stream st(dev);
    kernels::slice(st, x, at, y);
    kernels::slice_backward(st, dy, at, dx);
    st.run();
    EXPECT_EQ(y.download(), ref::slice(xv, s, at, o));
    // slice's adjoint: dy placed at `at`, zero elsewhere.
    const auto dxv = dx.download();
    std::vector<float> want(std::size_t(s.numel()), 0.f);
    std::size_t k = 0;
    for (std::int64_t n = 0; n < o.n; ++n)
      for (std::int64_t c = 0; c < o.c; ++c)
        for (std::int64_t i = 0; i < o.h; ++i)
          for (std::int64_t j = 0; j < o.w; ++j)
            want[std::size_t(((n * s.c + c + at.channel) * s.h + i + at.row) * s.w + j + at.col)] =
                dyv[k++];
    EXPECT_EQ(dxv, want);
  }
}

TEST(LayoutKernels, ConcatMatchesReference) {
  Device& dev = test::device();
  const std::uint32_t seed = 703;
  auto all = shapes(seed);
  all.push_back({17, 2, 3, 5});  // past kMaxCopies: the shader path instead of transfer copies
  for (Nchw s : all) {
    const std::vector<Nchw> parts = {{s.n, s.c, s.h, s.w}, {s.n, 1, s.h, s.w}, {s.n, 3, s.h, s.w}};
    SCOPED_TRACE(str(s) + " seed=" + std::to_string(seed));
    std::vector<std::vector<float>> values;
    std::vector<Tensor> xs, dxs;
    std::int64_t channels = 0;
    for (std::size_t k = 0; k < parts.size(); ++k) {
      values.push_back(test::random_floats(std::size_t(parts[k].numel()), seed + std::uint32_t(k)));
      xs.push_back(Tensor::from(dev, shape(parts[k]), values.back()));
      dxs.push_back(Tensor::empty(dev, shape(parts[k])));
      channels += parts[k].c;
    }
    Tensor y = Tensor::empty(dev, {s.n, channels, s.h, s.w});
    Stream st(dev);
    kernels::concat_channels(st, xs, y);
    kernels::concat_channels_backward(st, y, dxs);
    st.run();
    EXPECT_EQ(y.download(), ref::concat_channels(values, parts));
    for (std::size_t k = 0; k < parts.size(); ++k) EXPECT_EQ(dxs[k].download(), values[k]);
  }
}

TEST(LayoutKernels, ChannelAffineMatchesReference) {
  Device& dev = test::device();
  const std::uint32_t seed = 704;
  for (Nchw s : shapes(seed)) {
    SCOPED_TRACE(str(s) + " seed=" + std::to_string(seed));
    const auto xv = test::random_floats(std::size_t(s.numel()), seed);
    const auto dyv = test::random_floats(std::size_t(s.numel()), seed + 1);
    const auto sv = test::random_floats(std::size_t(s.c), seed + 2, 0.5f, 2.f);
    const auto bv = test::random_floats(std::size_t(s.c), seed + 3);
    Tensor x = Tensor::from(dev, shape(s), xv), y = Tensor::empty(dev, shape(s));
    Tensor scale = Tensor::from(dev, {s.c}, sv), bias = Tensor::from(dev, {s.c}, bv);
    Tensor dy = Tensor::from(dev, shape(s), dyv), dx = Tensor::empty(dev, shape(s));
    Tensor ds = Tensor::empty(dev, {s.c}), db = Tensor::empty(dev, {s.c});
    Stream st(dev);
    kernels::channel_affine(st, x, scale, bias, y);
    kernels::channel_affine_backward(st, x, scale, dy, &dx, &ds, &db);
    st.run();
    const auto want = ref::channel_affine(xv, s, sv, bv);
    const auto got = y.download();
    for (std::size_t i = 0; i < want.size(); ++i) ASSERT_NEAR(got[i], want[i], 1e-6);
    std::vector<float> rdx, rds, rdb;
    ref::channel_affine_backward(xv, s, sv, dyv, rdx, rds, rdb);
    EXPECT_EQ(dx.download(), rdx);
    const auto gds = ds.download(), gdb = db.download();
    const double tol = 1e-5 * double(s.n * s.h * s.w);  // fp32 sums of O(1) terms
    for (std::size_t c = 0; c < rds.size(); ++c) {
      EXPECT_NEAR(gds[c], rds[c], tol) << "dscale " << c;
      EXPECT_NEAR(gdb[c], rdb[c], tol) << "dbias " << c;
    }
  }
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
