#include <vkjr2/kernels/loss.hpp>
#include <vkjr2/kernels/ref/loss_ref.hpp>

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
                  double atol = 1e-7) {
  test::expect_all_near(got, want, rtol, atol);
}

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
  Device& dev = test::device();
  const std::uint32_t seed = 61;
  for (const Shape& shape : {Shape{1}, Shape{2, 3, 1, 1}, Shape{2, 3, 17, 9}, Shape{70001}}) {
    SCOPED_TRACE("shape " + shape.str() + " seed " + std::to_string(seed));
    const auto n = std::size_t(shape.numel());
    const auto pv = test::random_floats(n, seed), tv = test::random_floats(n, seed + 1);
    Tensor p = Tensor::from(dev, shape, pv), t = Tensor::from(dev, shape, tv);
    Tensor g = Tensor::from(dev, {1}, std::vector<float>{1.5f});
    for (int kind = 0; kind < 3; ++kind) {
      Tensor loss = Tensor::empty(dev, {1}), dp = Tensor::empty(dev, shape);
      Stream s(dev);
      run_pointwise(kind, s, p, t, loss);
      run_pointwise_backward(kind, s, p, t, g, dp);
      s.run();
      EXPECT_NEAR(loss.download()[0], ref::pointwise_loss(kind, pv, tv, kEps), 1e-5) << kind;
      expect_close(dp.download(), ref::pointwise_loss_backward(kind, pv, tv, kEps, 1.5f));
    }
  }
}

TEST(LossKernels, CosineAndCrossEntropyMatchReference) {
  Device& dev = test::device();
  const std::uint32_t seed = 62;
  for (auto [rows, k] : std::vector<std::pair<std::int64_t, std::int64_t>>{
           {1, 1}, {1, 10}, {3, 5}, {37, 17}, {5, 1000}}) {
    SCOPED_TRACE("rows " + std::to_string(rows) + " k " + std::to_string(k) + " seed " +
                 std::to_string(seed));
    const auto n = std::size_t(rows * k);
    const auto av = test::random_floats(n, seed), bv = test::random_floats(n, seed + 1);
    const auto dyv = test::random_floats(std::size_t(rows), seed + 2);
    std::vector<std::int32_t> labels(static_cast<std::size_t>(rows));
    for (std::size_t r = 0; r < labels.size(); ++r)
      labels[r] = std::int32_t((r * 7 + 3) % std::size_t(k));
    Tensor a = Tensor::from(dev, {rows, k}, av), b = Tensor::from(dev, {rows, k}, bv);
    Tensor dy = Tensor::from(dev, {rows}, dyv), y = Tensor::empty(dev, {rows});
    Tensor da = Tensor::empty(dev, {rows, k}), db = Tensor::empty(dev, {rows, k});
    Tensor lab = Tensor::empty(dev, {rows}, DType::i32);
    lab.upload_bytes(labels.data(), labels.size() * 4);
    Tensor xe = Tensor::empty(dev, {1}), dl = Tensor::empty(dev, {rows, k});
    Tensor g = Tensor::from(dev, {1}, std::vector<float>{0.5f});
    Stream s(dev);
    kernels::cosine_similarity(s, a, b, y);
    kernels::cosine_similarity_backward(s, a, b, dy, da, db);
    kernels::cross_entropy(s, a, lab, xe);
    kernels::cross_entropy_backward(s, a, lab, g, dl);
    s.run();
    std::vector<float> rda, rdb;
    ref::cosine_similarity_backward(av, bv, dyv, std::size_t(k), 1e-8f, rda, rdb);
    expect_close(y.download(), ref::cosine_similarity(av, bv, std::size_t(k), 1e-8f), 1e-4, 1e-6);
    expect_close(da.download(), rda, 1e-4, 1e-6);
    expect_close(db.download(), rdb, 1e-4, 1e-6);
    EXPECT_NEAR(xe.download()[0], ref::cross_entropy(av, labels, std::size_t(k)), 1e-5);
    expect_close(dl.download(), ref::cross_entropy_backward(av, labels, std::size_t(k), 0.5f), 1e-4,
                 1e-7);
  }
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
