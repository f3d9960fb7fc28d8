#include <vkjr2/kernels/loss.hpp>
#include <vkjr2/kernels/ref/loss_ref.hpp>

#include <gtest/gtest.h>

#include <cmath>
#include <string>
#include <vector>

#include "support/gradcheck.hpp"
#include "support/op_check.hpp"
#include "support/test_device.hpp"

namespace vkjr2 {
namespace {

using PointFwd = void (*)(Stream&, const Tensor&, const Tensor&, const Tensor&);
using PointBwd = void (*)(Stream&, const Tensor&, const Tensor&, const Tensor&, const Tensor&);
constexpr float kEps = 1e-2f;

void run_pointwise(int kind, Stream& s, const Tensor& p, const Tensor& t, const Tensor& loss) {
  if (kind == 0) kernels::l1_loss(s, p, t, loss);
  if (kind == 1) kernels::mse_loss(s, p, t, loss);
  if (kind == 2) kernels::charbonnier_loss(s, p, t, kEps, loss);
}
void run_pointwise_backward(int kind, Stream& s, const Tensor& p, const Tensor& t, const Tensor& g,
                            const Tensor& dp) {
  if (kind == 0) kernels::l1_loss_backward(s, p, t, g, dp);
  if (kind == 1) kernels::mse_loss_backward(s, p, t, g, dp);
  if (kind == 2) kernels::charbonnier_loss_backward(s, p, t, kEps, g, dp);
}

TEST(LossKernels, PointwiseLossesMatchReference) {
  const std::vector<Shape> edges = {{1}, {2, 3, 1, 1}, {2, 3, 17, 9}, {70001}};
  test::check_op("l1/mse/charbonnier", {.seed = 61, .cases = 8}, [&](test::OpCase& c) {
    const Shape shape = c.edge_or(edges, [&] { return c.nchw(3, 8, 64, 64); });
    c.describe("p, t " + shape.str());
    const auto pv = c.floats(shape.numel()), tv = c.floats(shape.numel());
    Tensor p = c.tensor(shape, pv), t = c.tensor(shape, tv);
    Tensor g = c.tensor({1}, std::vector<float>{1.5f});
    const char* names[3] = {"l1", "mse", "charbonnier"};
    for (int kind = 0; kind < 3; ++kind) {
      Tensor loss = c.empty({1}), dp = c.empty(shape);
      Stream s(c.device);
      run_pointwise(kind, s, p, t, loss);
      run_pointwise_backward(kind, s, p, t, g, dp);
      s.run();
      c.expect(names[kind], loss, {float(ref::pointwise_loss(kind, pv, tv, kEps))}, {0, 1e-5});
      c.expect(std::string(names[kind]) + " backward", dp,
               ref::pointwise_loss_backward(kind, pv, tv, kEps, 1.5f), {1e-4, 1e-7});
    }
  });
}

TEST(LossKernels, CosineAndCrossEntropyMatchReference) {
  const std::vector<Shape> edges = {{1, 1}, {1, 10}, {3, 5}, {37, 17}, {5, 1000}};
  test::check_op("cosine/cross_entropy", {.seed = 62, .cases = 9}, [&](test::OpCase& c) {
    const Shape shape = c.edge_or(edges, [&]() -> Shape {
      return {c.uniform(1, 40), c.uniform(1, 1200)};
    });
    const std::int64_t rows = shape[0], k = shape[1];
    c.describe("[rows, k] " + shape.str());
    const auto av = c.floats(rows * k), bv = c.floats(rows * k), dyv = c.floats(rows);
    std::vector<std::int32_t> labels(static_cast<std::size_t>(rows));
    for (auto& l : labels) l = c.uniform(0, int(k) - 1);
    Tensor a = c.tensor({rows, k}, av), b = c.tensor({rows, k}, bv);
    Tensor dy = c.tensor({rows}, dyv), y = c.empty({rows});
    Tensor da = c.empty({rows, k}), db = c.empty({rows, k});
    Tensor lab = c.empty({rows}, DType::i32);
    lab.upload_bytes(labels.data(), labels.size() * 4);
    Tensor xe = c.empty({1}), dl = c.empty({rows, k});
    Tensor g = c.tensor({1}, std::vector<float>{0.5f});
    Stream s(c.device);
    kernels::cosine_similarity(s, a, b, y);
    kernels::cosine_similarity_backward(s, a, b, dy, da, db);
    kernels::cross_entropy(s, a, lab, xe);
    kernels::cross_entropy_backward(s, a, lab, g, dl);
    s.run();
    std::vector<float> rda, rdb;
    ref::cosine_similarity_backward(av, bv, dyv, std::size_t(k), 1e-8f, rda, rdb);
    c.expect("cosine", y, ref::cosine_similarity(av, bv, std::size_t(k), 1e-8f), {1e-4, 1e-6});
    c.expect("cosine da", da, rda, {1e-4, 1e-6});
    c.expect("cosine db", db, rdb, {1e-4, 1e-6});
    c.expect("cross_entropy", xe, {float(ref::cross_entropy(av, labels, std::size_t(k)))},
             {0, 1e-5});
    c.expect("cross_entropy backward", dl,
             ref::cross_entropy_backward(av, labels, std::size_t(k), 0.5f), {1e-4, 1e-7});
  });
}

TEST(LossKernels, GradientsMatchFiniteDifferences) {
  Device& dev = test::device();
  const std::int64_t rows = 4, k = 6;
  const std::uint32_t seed = 63;
  SCOPED_TRACE("seed " + std::to_string(seed));
  const auto pv = test::random_floats(24, seed), tv = test::random_floats(24, seed + 1);
  const auto wv = test::random_floats(4, seed + 2);
  Tensor p = Tensor::from(dev, {rows, k}, pv), t = Tensor::from(dev, {rows, k}, tv);
  Tensor g = Tensor::from(dev, {1}, std::vector<float>{1.f}), w = Tensor::from(dev, {rows}, wv);
  Tensor dp = Tensor::empty(dev, {rows, k}), dq = Tensor::empty(dev, {rows, k});
  for (int kind = 0; kind < 3; ++kind) {
    Stream s(dev);
    run_pointwise_backward(kind, s, p, t, g, dp);
    s.run();
    auto loss = [&](std::span<const float> xs) {
      Tensor xt = Tensor::from(dev, {rows, k}, xs), o = Tensor::empty(dev, {1});
      Stream st(dev);
      run_pointwise(kind, st, xt, t, o);
      st.run();
      return double(o.download()[0]);
    };
    // L1's kink: random inputs stay ≥ step away from it with this seed.
    test::expect_gradient_matches(loss, pv, dp.download(), "pointwise " + std::to_string(kind),
                                  {.step = 1e-3});
  }
  {  // cosine: both inputs
    Stream s(dev);
    kernels::cosine_similarity_backward(s, p, t, w, dp, dq);
    s.run();
    auto loss = [&](std::span<const float> as, std::span<const float> bs) {
      Tensor at = Tensor::from(dev, {rows, k}, as), bt = Tensor::from(dev, {rows, k}, bs);
      Tensor o = Tensor::empty(dev, {rows});
      Stream st(dev);
      kernels::cosine_similarity(st, at, bt, o);
      st.run();
      return test::weighted_sum(o.download(), wv);
    };
    test::expect_gradient_matches([&](std::span<const float> v) { return loss(v, tv); }, pv,
                                  dp.download(), "cosine da", {.step = 1e-3});
    test::expect_gradient_matches([&](std::span<const float> v) { return loss(pv, v); }, tv,
                                  dq.download(), "cosine db", {.step = 1e-3});
  }
  {  // cross-entropy
    const std::vector<std::int32_t> labels = {0, 5, 2, 2};
    Tensor lab = Tensor::empty(dev, {rows}, DType::i32);
    lab.upload_bytes(labels.data(), 16);
    Stream s(dev);
    kernels::cross_entropy_backward(s, p, lab, g, dp);
    s.run();
    auto loss = [&](std::span<const float> xs) {
      Tensor xt = Tensor::from(dev, {rows, k}, xs), o = Tensor::empty(dev, {1});
      Stream st(dev);
      kernels::cross_entropy(st, xt, lab, o);
      st.run();
      return double(o.download()[0]);
    };
    test::expect_gradient_matches(loss, pv, dp.download(), "cross_entropy", {.step = 1e-2});
  }
}

TEST(LossKernels, BadLabelGivesNaNAndBadInputsAreClearErrors) {
  Device& dev = test::device();
  Tensor x = Tensor::from(dev, {2, 3}, std::vector<float>{1, 2, 3, 4, 5, 6});
  const std::vector<std::int32_t> labels = {1, 3};
  Tensor lab = Tensor::empty(dev, {2}, DType::i32);
  lab.upload_bytes(labels.data(), 8);
  Tensor loss = Tensor::empty(dev, {1});
  Stream s(dev);
  kernels::cross_entropy(s, x, lab, loss);
  s.run();
  EXPECT_TRUE(std::isnan(loss.download()[0]));
  Tensor y = Tensor::empty(dev, {3, 2}), two = Tensor::empty(dev, {2});
  EXPECT_THROW(kernels::mse_loss(s, x, y, loss), InvalidArgument);
  EXPECT_THROW(kernels::l1_loss(s, x, x, two), InvalidArgument);
  EXPECT_THROW(kernels::charbonnier_loss(s, x, x, 0.f, loss), InvalidArgument);
  EXPECT_THROW(kernels::cross_entropy(s, x, two, loss), InvalidArgument);
  EXPECT_THROW(kernels::cosine_similarity(s, x, x, loss), InvalidArgument);
  EXPECT_THROW(kernels::mse_loss(s, Tensor::empty(dev, {0}), Tensor::empty(dev, {0}), loss),
               InvalidArgument);
}

}  // namespace
}  // namespace vkjr2
