#include <vkjr2/kernels/grid_sample.hpp>
#include <vkjr2/kernels/ref/grid_sample_ref.hpp>

#include <gtest/gtest.h>

#include <cmath>
#include <random>
#include <string>
#include <vector>

#include "support/expect_error.hpp"
#include "support/gradcheck.hpp"
#include "support/op_check.hpp"
#include "support/test_device.hpp"

namespace vkjr2 {
namespace {

using kernels::GridSampleOptions;
using kernels::SamplePadding;

// 1×1 inputs and outputs, odd sizes, output pixel counts that do not divide
// the 128-pixel workgroup, channel counts around the ×4 unrolled loop.
const std::vector<ref::SampleDims> kDims = {
    {1, 1, 1, 1, 1, 1},  {1, 3, 17, 23, 9, 11}, {2, 4, 9, 12, 21, 5}, {1, 64, 6, 7, 6, 7},
    {3, 5, 13, 1, 4, 3}, {2, 1, 1, 31, 7, 8},   {1, 2, 5, 5, 1, 1},   {1, 6, 40, 33, 30, 41}};

std::vector<GridSampleOptions> all_options() {
  std::vector<GridSampleOptions> v;
  for (SamplePadding p : {SamplePadding::zeros, SamplePadding::border}) {
    for (bool align : {false, true}) v.push_back({p, align});
  }
  return v;
}

std::string dims_name(const ref::SampleDims& d) {
  return "N" + std::to_string(d.n) + " C" + std::to_string(d.c) + " in " + std::to_string(d.in_h) +
         "x" + std::to_string(d.in_w) + " out " + std::to_string(d.out_h) + "x" +
         std::to_string(d.out_w);
}

std::string name(const ref::SampleDims& d, const GridSampleOptions& o) {
  return dims_name(d) + (o.padding == SamplePadding::zeros ? " zeros" : " border") +
         (o.align_corners ? " align" : " no-align");
}

std::size_t img_numel(const ref::SampleDims& d) { return std::size_t(d.n) * d.c * d.in_h * d.in_w; }
std::size_t out_numel(const ref::SampleDims& d) {
  return std::size_t(d.n) * d.c * d.out_h * d.out_w;
}
std::size_t grid_numel(const ref::SampleDims& d) {
  return std::size_t(d.n) * d.out_h * d.out_w * 2;
}

// A grid whose pixel positions have fractional parts in [0.15, 0.85] (never
// near a pixel edge, where bilinear sampling is not differentiable and float
// rounding could pick another cell), from 2 pixels outside to 2 inside each
// edge.
std::vector<float> smooth_grid(const ref::SampleDims& d, bool align, std::uint32_t seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> frac(0.15, 0.85);
  std::vector<float> g(grid_numel(d));
  for (std::size_t i = 0; i < g.size(); ++i) {
    const int size = i % 2 == 0 ? d.in_w : d.in_h;
    if (align && size == 1) {  // every grid value samples pixel 0
      g[i] = std::uniform_real_distribution<float>(-1, 1)(rng);
      continue;
    }
    const double pos = std::uniform_int_distribution<int>(-2, size + 1)(rng) + frac(rng);
    g[i] = static_cast<float>(align ? pos / (size - 1) * 2 - 1 : (2 * pos + 1) / size - 1);
  }
  return g;
}

// The edge dimensions, then random ones.
ref::SampleDims draw_dims(test::OpCase& c) {
  if (c.index < int(kDims.size())) return kDims[std::size_t(c.index)];
  return {c.uniform(1, 3),  c.uniform(1, 12), c.uniform(1, 40),
          c.uniform(1, 40), c.uniform(1, 40), c.uniform(1, 40)};
}

std::vector<float> run_forward(Device& dev, const ref::SampleDims& d, std::span<const float> in,
                               std::span<const float> grid, GridSampleOptions o) {
  Tensor ti = Tensor::from(dev, {d.n, d.c, d.in_h, d.in_w}, in);
  Tensor tg = Tensor::from(dev, {d.n, d.out_h, d.out_w, 2}, grid);
  Tensor to = Tensor::empty(dev, {d.n, d.c, d.out_h, d.out_w});
  Stream s(dev);
  kernels::grid_sample(s, ti, tg, to, o);
  s.run();
  return to.download();
}

struct Grads {
  std::vector<float> d_input, d_grid;
};

Grads run_backward(Device& dev, const ref::SampleDims& d, std::span<const float> in,
                   std::span<const float> grid, std::span<const float> d_out, GridSampleOptions o) {
  Tensor ti = Tensor::from(dev, {d.n, d.c, d.in_h, d.in_w}, in);
  Tensor tg = Tensor::from(dev, {d.n, d.out_h, d.out_w, 2}, grid);
  Tensor td = Tensor::from(dev, {d.n, d.c, d.out_h, d.out_w}, d_out);
  Tensor di = Tensor::empty(dev, ti.shape()), dg = Tensor::empty(dev, tg.shape());
  Stream s(dev);
  kernels::grid_sample_backward(s, ti, tg, td, &di, &dg, o);
  s.run();
  return {di.download(), dg.download()};
}

TEST(GridSampleKernel, ForwardMatchesReference) {
  test::check_op("grid_sample", {.seed = 31, .cases = 12}, [](test::OpCase& c) {
    const ref::SampleDims d = draw_dims(c);
    c.describe(dims_name(d));
    const auto in = c.floats(std::int64_t(img_numel(d)));
    // Raw random grid, partly outside [-1, 1].
    const auto grid = c.floats(std::int64_t(grid_numel(d)), -1.3f, 1.3f);
    for (const auto& o : all_options()) {
      const auto want = ref::grid_sample(in, grid, d, o);
      c.expect("out " + name(d, o), run_forward(c.device, d, in, grid, o), want,
               test::peak_relative(want, 1e-4));
    }
  });
}

TEST(GridSampleKernel, BackwardMatchesReference) {
  test::check_op("grid_sample backward", {.seed = 32, .cases = 12}, [](test::OpCase& c) {
    const ref::SampleDims d = draw_dims(c);
    c.describe(dims_name(d));
    const auto in = c.floats(std::int64_t(img_numel(d)));
    const auto d_out = c.floats(std::int64_t(out_numel(d)));
    for (const auto& o : all_options()) {
      const auto grid = smooth_grid(d, o.align_corners, c.seed + 1);
      const Grads got = run_backward(c.device, d, in, grid, d_out, o);
      std::vector<float> d_input, d_grid;
      ref::grid_sample_backward(in, grid, d_out, d, o, d_input, d_grid);
      c.expect("d_input " + name(d, o), got.d_input, d_input, test::peak_relative(d_input, 1e-4));
      c.expect("d_grid " + name(d, o), got.d_grid, d_grid, test::peak_relative(d_grid, 1e-4));
    }
  });
}

TEST(GridSampleKernel, GradcheckInput) {
  Device& dev = test::device();
  const ref::SampleDims d{1, 2, 5, 6, 4, 7};
  const std::uint32_t seed = 41;
  for (const auto& o : all_options()) {
    SCOPED_TRACE(name(d, o) + " seed=" + std::to_string(seed));
    const auto in = test::random_floats(img_numel(d), seed);
    const auto grid = smooth_grid(d, o.align_corners, seed + 1);
    const auto w = test::random_floats(out_numel(d), seed + 2);
    const Grads g = run_backward(dev, d, in, grid, w, o);
    auto loss = [&](std::span<const float> x) {
      return test::weighted_sum(run_forward(dev, d, x, grid, o), w);
    };
    test::expect_gradient_matches(loss, in, g.d_input, "d_input", {.seed = seed});
  }
}

TEST(GridSampleKernel, GradcheckGrid) {
  Device& dev = test::device();
  const ref::SampleDims d{2, 3, 5, 6, 3, 4};
  const std::uint32_t seed = 42;
  for (const auto& o : all_options()) {
    SCOPED_TRACE(name(d, o) + " seed=" + std::to_string(seed));
    const auto in = test::random_floats(img_numel(d), seed);
    const auto grid = smooth_grid(d, o.align_corners, seed + 1);
    const auto w = test::random_floats(out_numel(d), seed + 2);
    const Grads g = run_backward(dev, d, in, grid, w, o);
    auto loss = [&](std::span<const float> x) {
      return test::weighted_sum(run_forward(dev, d, in, x, o), w);
    };
    // step 2e-3 in normalized units is at most 0.006 px here, far from the
    // 0.15 px margin to the nearest pixel edge.
    test::expect_gradient_matches(loss, grid, g.d_grid, "d_grid", {.step = 2e-3, .seed = seed});
  }
}

TEST(GridSampleKernel, BackwardIsDeterministic) {
  Device& dev = test::device();
  const ref::SampleDims d{2, 3, 20, 20, 37, 41};  // upsampling: many hits per input pixel
  const GridSampleOptions o{SamplePadding::zeros, false};
  const auto in = test::random_floats(img_numel(d), 1);
  const auto grid = test::random_floats(grid_numel(d), 2, -1.1f, 1.1f);
  const auto d_out = test::random_floats(out_numel(d), 3);
  const Grads a = run_backward(dev, d, in, grid, d_out, o);
  const Grads b = run_backward(dev, d, in, grid, d_out, o);
  EXPECT_EQ(a.d_input, b.d_input);
  EXPECT_EQ(a.d_grid, b.d_grid);
}

// affine_grid with the identity theta followed by grid_sample returns the
// input exactly, for both align_corners conventions.
TEST(GridSampleKernel, IdentityAffineReproducesInput) {
  Device& dev = test::device();
  const int n = 2, c = 3, h = 7, w = 10;
  const auto in = test::random_floats(std::size_t(n) * c * h * w, 9);
  const std::vector<float> theta = {1, 0, 0, 0, 1, 0, 1, 0, 0, 0, 1, 0};
  for (bool align : {false, true}) {
    SCOPED_TRACE(align ? "align" : "no-align");
    Tensor tt = Tensor::from(dev, {n, 2, 3}, theta);
    Tensor grid = Tensor::empty(dev, {n, h, w, 2});
    Tensor ti = Tensor::from(dev, {n, c, h, w}, in);
    Tensor out = Tensor::empty(dev, {n, c, h, w});
    Stream s(dev);
    kernels::affine_grid(s, tt, grid, align);
    kernels::grid_sample(s, ti, grid, out, {SamplePadding::zeros, align});
    s.run();
    test::expect_all_close("out", out.download(), in, test::peak_relative(in, 1e-4));
  }
}

TEST(GridSampleKernel, NonFiniteGridGivesNaN) {
  Device& dev = test::device();
  const ref::SampleDims d{1, 2, 4, 4, 1, 3};
  const std::vector<float> in(32, 1.f);
  const std::vector<float> grid = {0.1f, 0.2f, NAN, 0.f, 0.f, -INFINITY};
  const auto out = run_forward(dev, d, in, grid, {});
  for (int ch = 0; ch < 2; ++ch) {
    EXPECT_FALSE(std::isnan(out[ch * 3 + 0]));
    EXPECT_TRUE(std::isnan(out[ch * 3 + 1]));
    EXPECT_TRUE(std::isnan(out[ch * 3 + 2]));
  }
}

TEST(GridSampleKernel, BadInputsAreClearErrors) {
  Device& dev = test::device();
  Stream s(dev);
  Tensor in = Tensor::empty(dev, {2, 3, 8, 8});
  Tensor grid = Tensor::empty(dev, {2, 5, 6, 2});
  Tensor out = Tensor::empty(dev, {2, 3, 5, 6});
  Tensor grid3 = Tensor::empty(dev, {2, 5, 6, 3});
  test::expect_invalid_argument([&] { kernels::grid_sample(s, in, grid3, out); }, "grid");
  Tensor grid_batch = Tensor::empty(dev, {1, 5, 6, 2});
  test::expect_invalid_argument([&] { kernels::grid_sample(s, in, grid_batch, out); }, "grid");
  Tensor bad_out = Tensor::empty(dev, {2, 3, 6, 5});
  test::expect_invalid_argument([&] { kernels::grid_sample(s, in, grid, bad_out); }, "out");
  Tensor empty = Tensor::empty(dev, {2, 3, 0, 8});
  test::expect_invalid_argument([&] { kernels::grid_sample(s, empty, grid, out); }, "empty");
  test::expect_invalid_argument(
      [&] { kernels::grid_sample_backward(s, in, grid, out, nullptr, nullptr); }, "null");
  test::expect_invalid_argument(
      [&] { kernels::grid_sample_backward(s, in, grid, out, &out, nullptr); }, "d_input");
  test::expect_invalid_argument(
      [&] { kernels::grid_sample_backward(s, in, grid, out, nullptr, &out); }, "d_grid");
  Tensor theta = Tensor::empty(dev, {2, 3, 2});
  test::expect_invalid_argument([&] { kernels::affine_grid(s, theta, grid, false); }, "theta");
  Tensor theta1 = Tensor::empty(dev, {1, 2, 3});
  test::expect_invalid_argument([&] { kernels::affine_grid(s, theta1, grid, false); }, "theta");
  test::expect_invalid_argument(
      [&] {
        kernels::affine_grid(s, Tensor::empty(dev, {2, 2, 3}), grid3, false);
      },
      "grid");
  test::expect_invalid_argument(
      [&] {
        kernels::affine_grid_backward(s, grid, Tensor::empty(dev, {2, 6}), false);
      },
      "d_theta");
}

// ---- affine_grid ------------------------------------------------------------

struct AffineDims {
  int n, h, w;
};
const std::vector<AffineDims> kAffineDims = {
    {1, 1, 1}, {2, 5, 7}, {3, 1, 9}, {1, 33, 17}, {2, 64, 70}};

std::vector<float> run_affine(Device& dev, const AffineDims& d, std::span<const float> theta,
                              bool align) {
  Tensor tt = Tensor::from(dev, {d.n, 2, 3}, theta);
  Tensor grid = Tensor::empty(dev, {d.n, d.h, d.w, 2});
  Stream s(dev);
  kernels::affine_grid(s, tt, grid, align);
  s.run();
  return grid.download();
}

std::vector<float> run_affine_backward(Device& dev, const AffineDims& d,
                                       std::span<const float> d_grid, bool align) {
  Tensor tg = Tensor::from(dev, {d.n, d.h, d.w, 2}, d_grid);
  Tensor dt = Tensor::empty(dev, {d.n, 2, 3});
  Stream s(dev);
  kernels::affine_grid_backward(s, tg, dt, align);
  s.run();
  return dt.download();
}

TEST(AffineGridKernel, ForwardAndBackwardMatchReference) {
  test::check_op("affine_grid", {.seed = 51, .cases = 9}, [](test::OpCase& c) {
    const AffineDims d = c.index < int(kAffineDims.size())
                             ? kAffineDims[std::size_t(c.index)]
                             : AffineDims{c.uniform(1, 3), c.uniform(1, 80), c.uniform(1, 80)};
    c.describe("N" + std::to_string(d.n) + " " + std::to_string(d.h) + "x" + std::to_string(d.w));
    const auto theta = c.floats(std::int64_t(d.n) * 6, -2, 2);
    const auto d_grid = c.floats(std::int64_t(d.n) * d.h * d.w * 2);
    for (bool align : {false, true}) {
      const std::string how = align ? " (align)" : " (no align)";
      const auto want = ref::affine_grid(theta, d.n, d.h, d.w, align);
      c.expect("grid" + how, run_affine(c.device, d, theta, align), want,
               test::peak_relative(want, 1e-4));
      const auto want_dt = ref::affine_grid_backward(d_grid, d.n, d.h, d.w, align);
      c.expect("d_theta" + how, run_affine_backward(c.device, d, d_grid, align), want_dt,
               test::peak_relative(want_dt, 1e-4));
    }
  });
}

// Values PyTorch's affine_grid gives for the identity theta.
TEST(AffineGridKernel, IdentityKnownValues) {
  Device& dev = test::device();
  const std::vector<float> theta = {1, 0, 0, 0, 1, 0};
  // align_corners=True, W=3, H=1: x = -1, 0, 1; y = 0 (a single row).
  EXPECT_EQ(run_affine(dev, {1, 1, 3}, theta, true), (std::vector<float>{-1, 0, 0, 0, 1, 0}));
  // align_corners=False, W=2, H=2: x, y = ±0.5.
  EXPECT_EQ(run_affine(dev, {1, 2, 2}, theta, false),
            (std::vector<float>{-0.5f, -0.5f, 0.5f, -0.5f, -0.5f, 0.5f, 0.5f, 0.5f}));
}

TEST(AffineGridKernel, GradcheckTheta) {
  Device& dev = test::device();
  const AffineDims d{2, 4, 5};
  const std::uint32_t seed = 52;
  for (bool align : {false, true}) {
    SCOPED_TRACE(std::string(align ? "align" : "no-align") + " seed=" + std::to_string(seed));
    const auto theta = test::random_floats(std::size_t(d.n) * 6, seed);
    const auto w = test::random_floats(std::size_t(d.n) * d.h * d.w * 2, seed + 1);
    const auto d_theta = run_affine_backward(dev, d, w, align);
    auto loss = [&](std::span<const float> x) {
      return test::weighted_sum(run_affine(dev, d, x, align), w);
    };
    test::expect_gradient_matches(loss, theta, d_theta, "d_theta", {.seed = seed});
  }
}

}  // namespace
}  // namespace vkjr2
