#include <vkjr2/kernels/flow.hpp>
#include <vkjr2/kernels/ref/flow_ref.hpp>

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <string>
#include <vector>

#include "support/expect_error.hpp"
#include "support/op_check.hpp"
#include "support/test_device.hpp"

namespace vkjr2 {
namespace {

struct Case {
  int n, ref_images, h, w;
  kernels::LucasKanade p;
};

// Edge cases (one pixel, one row, a window wider than the image, one
// reference for a batch, a radius-0 window whose tensor is singular), then
// random ones.
const std::vector<Case> kEdges = {
    {1, 1, 1, 1, {2, 1e-3f}},   {2, 1, 1, 9, {1, 1e-3f}},   {1, 1, 7, 5, {6, 1e-3f}},
    {3, 1, 13, 17, {3, 1e-3f}}, {2, 2, 16, 16, {0, 1e-3f}}, {1, 1, 31, 29, {5, 1e-3f}},
};
constexpr int kCases = 12;

std::vector<float> as_float(const std::vector<double>& v) { return {v.begin(), v.end()}; }

TEST(FlowKernels, LucasKanadeStepMatchesReference) {
  test::check_op("lucas_kanade_step", {.seed = 701, .cases = kCases}, [](test::OpCase& c) {
    Case k = c.index < int(kEdges.size()) ? kEdges[std::size_t(c.index)] : Case{};
    if (c.index >= int(kEdges.size())) {
      k.n = c.uniform(1, 3);
      k.ref_images = c.uniform(0, 1) ? k.n : 1;
      k.h = c.uniform(1, 40);
      k.w = c.uniform(1, 40);
      k.p = {c.uniform(0, 6), 1e-3f};
    }
    c.describe("n " + std::to_string(k.n) + " ref " + std::to_string(k.ref_images) + " " +
               std::to_string(k.h) + "x" + std::to_string(k.w) + " radius " +
               std::to_string(k.p.radius));
    const std::int64_t plane = std::int64_t(k.h) * k.w;
    const auto refv = c.floats(k.ref_images * plane);
    const auto imgv = c.floats(k.n * plane);
    const auto flowv = c.floats(k.n * 2 * plane, -2.f, 2.f);
    Tensor ref = c.tensor({k.ref_images, 1, k.h, k.w}, refv);
    Tensor img = c.tensor({k.n, 1, k.h, k.w}, imgv);
    Tensor flow = c.tensor({k.n, 2, k.h, k.w}, flowv);
    Tensor flow_out = c.empty({k.n, 2, k.h, k.w}), eig = c.empty({k.n, 1, k.h, k.w});
    Stream s(c.device);
    kernels::lucas_kanade_step(s, ref, img, flow, flow_out, eig, k.p);
    s.run();
    const auto want = ref::lucas_kanade_step(refv, k.ref_images, imgv, flowv, k.n, k.h, k.w, k.p);
    std::vector<double> flow_bound(want.flow.size()), eig_bound(want.min_eig.size());
    for (std::int64_t b = 0; b < k.n; ++b) {
      for (std::int64_t i = 0; i < plane; ++i) {
        const std::size_t e = std::size_t(b * plane + i);
        const double lmin = want.min_eig[e];
        // λmax from the reference's λmin and the trace is not stored; bound
        // the eigenvalue by the cancellation of its two terms and the flow
        // by the update's size times the condition number.
        const double dx =
            want.flow[std::size_t(2 * b * plane + i)] - flowv[std::size_t(2 * b * plane + i)];
        const double dy = want.flow[std::size_t((2 * b + 1) * plane + i)] -
                          flowv[std::size_t((2 * b + 1) * plane + i)];
        const double cond = lmin >= k.p.min_eigenvalue ? 1.0 / lmin : 0.0;
        const double step = std::abs(dx) + std::abs(dy);
        eig_bound[e] = 1e-6 + 1e-5 * std::abs(lmin);
        for (int a = 0; a < 2; ++a) {
          const std::size_t f = std::size_t((2 * b + a) * plane + i);
          flow_bound[f] = 1e-5 * (1 + std::abs(want.flow[f])) + 2e-6 * cond * (1 + step);
        }
        // A pixel at the threshold could go either way in float.
        ASSERT_FALSE(std::abs(lmin - k.p.min_eigenvalue) < 1e-5) << "a pixel at the threshold";
      }
    }
    c.expect("min_eig", eig, as_float(want.min_eig), eig_bound);
    c.expect("flow_out", flow_out, as_float(want.flow), flow_bound);
  });
}

// A smooth pattern shifted by a known sub-pixel displacement: a few steps
// from zero find it in the interior (the semantics img(x + flow) ≈ ref), and
// many more steps do not drift away (the triangular window keeps the coupled
// iteration stable; a box window does not). What remains is the bilinear
// interpolation's own bias at these frequencies (a few hundredths of a pixel).
TEST(FlowKernels, LucasKanadeStepsFindAShift) {
  Device& dev = test::device();
  const int h = 48, w = 56;
  const double sx = 0.7, sy = -1.3;
  auto pattern = [](double x, double y) {
    return 0.5 + 0.2 * std::sin(0.31 * x) + 0.15 * std::cos(0.27 * y) +
           0.1 * std::sin(0.19 * (x + y));
  };
  std::vector<float> refv(std::size_t(h) * w), imgv(refv.size());
  for (int y = 0; y < h; ++y) {
    for (int x = 0; x < w; ++x) {
      refv[std::size_t(y) * w + x] = float(pattern(x, y));
      imgv[std::size_t(y) * w + x] = float(pattern(x - sx, y - sy));
    }
  }
  Tensor ref = Tensor::from(dev, {1, 1, h, w}, refv), img = Tensor::from(dev, {1, 1, h, w}, imgv);
  Tensor a = Tensor::from(dev, {1, 2, h, w}, std::vector<float>(std::size_t(2) * h * w, 0.f));
  Tensor b = Tensor::empty(dev, {1, 2, h, w});
  Stream s(dev);
  int done = 0;
  for (int steps : {8, 30}) {
    for (; done < steps; ++done) {
      kernels::lucas_kanade_step(s, ref, img, a, b, Tensor(), {3, 1e-5f});
      std::swap(a, b);
    }
    s.run();
    const auto f = a.download();
    const int margin = 8;  // near the edge the window holds fewer samples
    std::vector<double> err;
    for (int y = margin; y < h - margin; ++y) {
      for (int x = margin; x < w - margin; ++x) {
        const std::size_t i = std::size_t(y) * w + x;
        err.push_back(std::abs(f[i] - sx));
        err.push_back(std::abs(f[std::size_t(h) * w + i] - sy));
      }
    }
    std::sort(err.begin(), err.end());
    EXPECT_LT(err[err.size() / 2], 0.03) << "median interior error after " << steps << " steps, px";
    EXPECT_LT(err.back(), 0.15) << "largest interior error after " << steps << " steps, px";
  }
}

TEST(FlowKernels, LucasKanadeBadArgumentsAreClearErrors) {
  Device& dev = test::device();
  Tensor ref = Tensor::empty(dev, {1, 1, 8, 8}), img = Tensor::empty(dev, {2, 1, 8, 8});
  Tensor flow = Tensor::empty(dev, {2, 2, 8, 8}), out = Tensor::empty(dev, {2, 2, 8, 8});
  Stream s(dev);
  test::expect_invalid_argument(
      [&] {
        kernels::lucas_kanade_step(s, Tensor::empty(dev, {3, 1, 8, 8}), img, flow, out, {});
      },
      "ref [3, 1, 8, 8] must be 1×1×H×W or N×1×H×W");
  test::expect_invalid_argument(
      [&] {
        kernels::lucas_kanade_step(s, ref, Tensor::empty(dev, {2, 3, 8, 8}), flow, out, {});
      },
      "must have one channel");
  test::expect_invalid_argument([&] { kernels::lucas_kanade_step(s, ref, img, flow, flow, {}); },
                                "flow_out must not be flow_in");
  test::expect_invalid_argument(
      [&] {
        kernels::lucas_kanade_step(s, ref, img, flow, out, {}, {3, 0.f});
      },
      "min_eigenvalue");
  test::expect_invalid_argument(
      [&] {
        kernels::lucas_kanade_step(s, ref, img, flow, out, {}, {-1, 1e-3f});
      },
      "radius -1");
}

}  // namespace
}  // namespace vkjr2
