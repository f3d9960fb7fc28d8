// AdaFaceHead: logits against a double-precision host implementation of the
// paper's head, gradients through the tape against finite differences, the
// running norm statistics in train and eval mode, and a short training run.
#include <vkjr2/nets/adaface.hpp>
#include <vkjr2/nets/layers.hpp>
#include <vkjr2/nets/optimizer.hpp>
#include <vkjr2/nets/safetensors.hpp>
#include <vkjr2/runtime/error.hpp>

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <numbers>
#include <random>
#include <string>
#include <utility>
#include <vector>

#include "support/gradcheck.hpp"
#include "support/op_check.hpp"
#include "support/test_device.hpp"

namespace vkjr2::nets {
namespace {

using Labels = std::vector<std::int32_t>;

Tensor labels_tensor(const Device& dev, const Labels& labels) {
  Tensor t = Tensor::empty(dev, Shape{std::int64_t(labels.size())}, DType::i32);
  t.upload_bytes(labels.data(), labels.size() * sizeof(std::int32_t));
  return t;
}

// The head as the official PyTorch module computes it, in double.
// mu / sigma are updated in place when `train`.
std::vector<double> host_adaface(const std::vector<float>& z, const std::vector<float>& w,
                                 const Labels& labels, std::size_t d, std::size_t c,
                                 const AdaFaceOptions& o, bool train, double& mu, double& sigma) {
  const std::size_t b = labels.size();
  std::vector<double> norm(b), safe(b);
  for (std::size_t i = 0; i < b; ++i) {
    double ss = 0;
    for (std::size_t k = 0; k < d; ++k) ss += double(z[i * d + k]) * z[i * d + k];
    norm[i] = std::sqrt(ss);
    safe[i] = std::clamp(norm[i], 0.001, 100.0);
  }
  if (train) {
    double mean = 0, var = 0;
    for (double n : safe) mean += n / double(b);
    for (double n : safe) var += (n - mean) * (n - mean) / double(b - 1);
    mu = o.alpha * mean + (1 - o.alpha) * mu;
    sigma = o.alpha * std::sqrt(var) + (1 - o.alpha) * sigma;
  }
  std::vector<double> wnorm(c);
  for (std::size_t j = 0; j < c; ++j) {
    double ss = 0;
    for (std::size_t k = 0; k < d; ++k) ss += double(w[k * c + j]) * w[k * c + j];
    wnorm[j] = std::sqrt(ss);
  }
  const double eps = o.eps, m = o.m, pi = std::numbers::pi;
  std::vector<double> out(b * c);
  for (std::size_t i = 0; i < b; ++i) {
    const double zhat = std::clamp(o.h * (safe[i] - mu) / (sigma + eps), -1.0, 1.0);
    for (std::size_t j = 0; j < c; ++j) {
      double dot = 0;
      for (std::size_t k = 0; k < d; ++k) dot += double(z[i * d + k]) * w[k * c + j];
      const double cs = std::clamp(dot / (norm[i] * wnorm[j]), -1 + eps, 1 - eps);
      const bool target = std::int32_t(j) == labels[i];
      const double theta = std::clamp(std::acos(cs) - (target ? m * zhat : 0.0), eps, pi - eps);
      out[i * c + j] = o.s * (std::cos(theta) - (target ? m + m * zhat : 0.0));
    }
  }
  return out;
}

void expect_near_double(const std::vector<float>& got, const std::vector<double>& want, double rtol,
                        double atol) {
  ASSERT_EQ(got.size(), want.size());
  for (std::size_t i = 0; i < got.size(); ++i) {
    ASSERT_NEAR(got[i], want[i], atol + rtol * std::fabs(want[i])) << "at " << i;
  }
}

std::vector<float> logits_of(Tape& t, const AdaFaceHead& head, const Tensor& z,
                             const Tensor& labels) {
  const Var y = head.forward(t, Var(z), labels);
  t.stream().run();
  return y.value().download();
}

Labels random_labels(std::size_t n, std::size_t classes, std::uint32_t seed) {
  std::mt19937 rng(seed);
  Labels out(n);
  for (auto& l : out) l = std::int32_t(rng() % classes);
  return out;
}

TEST(AdaFaceHead, LogitsMatchHostAndStatisticsUpdateOnlyInTraining) {
  Device& dev = test::device();
  const std::uint32_t seed = 81;
  SCOPED_TRACE("seed " + std::to_string(seed));
  const std::size_t b = 9, d = 13, c = 37;
  AdaFaceHead head(dev, int(d), int(c), seed);
  const auto w = head.weight.value().download();
  Stream s(dev);
  Tape t(s, false);
  double mu = 20, sigma = 100;
  for (int step = 0; step < 3; ++step) {
    // Norms from ~1 to ~30 so ẑ and its clip both matter once μ, σ move.
    auto z = test::random_floats(b * d, seed + 10 * std::uint32_t(step), -8.f, 8.f);
    for (std::size_t i = 0; i < b; ++i) {
      for (std::size_t k = 0; k < d; ++k) z[i * d + k] *= float(i + 1) / float(b);
    }
    const Labels labels = random_labels(b, c, seed + 1 + std::uint32_t(step));
    const bool train = step < 2;
    head.train(train);
    const double mu_before = mu, sigma_before = sigma;
    const float mu_device = head.running_mean.value().download()[0];
    const float sigma_device = head.running_std.value().download()[0];
    const auto want = host_adaface(z, w, labels, d, c, head.options, train, mu, sigma);
    const auto got =
        logits_of(t, head, Tensor::from(dev, Shape{std::int64_t(b), std::int64_t(d)}, z),
                  labels_tensor(dev, labels));
    SCOPED_TRACE("step " + std::to_string(step));
    expect_near_double(got, want, 1e-4, 2e-3);
    EXPECT_NEAR(head.running_mean.value().download()[0], mu, 1e-5 * mu);
    EXPECT_NEAR(head.running_std.value().download()[0], sigma, 1e-5 * sigma);
    if (train) {
      EXPECT_NE(mu, mu_before);
      EXPECT_NE(sigma, sigma_before);
    } else {
      EXPECT_EQ(mu, mu_before);
      EXPECT_EQ(head.running_mean.value().download()[0], mu_device);
      EXPECT_EQ(head.running_std.value().download()[0], sigma_device);
    }
  }
  // Buffers and parameter are registered under the official module's names.
  ASSERT_EQ(head.named_parameters().size(), 1u);
  EXPECT_EQ(head.named_parameters()[0].first, "kernel");
  ASSERT_EQ(head.named_buffers().size(), 2u);
  EXPECT_EQ(head.named_buffers()[0].first, "batch_mean");
  EXPECT_EQ(head.named_buffers()[1].first, "batch_std");
}

// Σ w ⊙ logits through the tape; returns d/dz (and fills d/dW).
struct Grads {
  std::vector<float> dz, dw;
};
Grads tape_gradients(const AdaFaceHead& head, const Tensor& z, const Tensor& labels,
                     const Tensor& weights) {
  const Device dev = z.device();
  Stream s(dev);
  Tape t(s);
  head.zero_grad();
  const Var zv(z, true);
  const Var loss = sum_all(t, mul(t, head.forward(t, zv, labels), Var(weights)));
  t.backward(loss);
  s.run();
  return {zv.grad().download(), head.weight.grad().download()};
}

TEST(AdaFaceHead, GradientsReachEmbeddingsAndWeightsThroughTheTape) {
  Device& dev = test::device();
  const std::uint32_t seed = 82;
  SCOPED_TRACE("seed " + std::to_string(seed));
  const std::int64_t b = 4, d = 5, c = 3;
  AdaFaceHead head(dev, int(d), int(c), seed);
  head.eval();  // fixed μ, σ: ẑ depends on the current norms only
  // Rows with norms 4, 7, 13, 16 around μ = 10.
  auto zv = test::random_floats(std::size_t(b * d), seed + 1);
  const float target_norm[4] = {4.f, 7.f, 13.f, 16.f};
  for (std::int64_t i = 0; i < b; ++i) {
    double ss = 0;
    for (std::int64_t k = 0; k < d; ++k)
      ss += double(zv[std::size_t(i * d + k)]) * zv[std::size_t(i * d + k)];
    for (std::int64_t k = 0; k < d; ++k)
      zv[std::size_t(i * d + k)] *= float(target_norm[i] / std::sqrt(ss));
  }
  const Labels labels = {0, 2, 1, 2};
  const Tensor lab = labels_tensor(dev, labels);
  const auto wts = test::random_floats(std::size_t(b * c), seed + 2);
  const Tensor weights = Tensor::from(dev, Shape{b, c}, wts);
  const auto w0 = head.weight.value().download();
  Stream s(dev);
  Tape t(s, false);
  auto loss_at = [&](const std::vector<float>& z) {
    return test::weighted_sum(logits_of(t, head, Tensor::from(dev, Shape{b, d}, z), lab), wts);
  };

  // ẑ is detached: with σ = 0.01 every ẑ sits at its clip (±1), so finite
  // differences in z (which move ‖z‖ by ≤ the step) see no ẑ change either.
  head.running_mean.value().upload(std::vector<float>{10.f});
  head.running_std.value().upload(std::vector<float>{0.01f});
  const Grads g = tape_gradients(head, Tensor::from(dev, Shape{b, d}, zv), lab, weights);
  test::expect_gradient_matches(
      [&](std::span<const float> x) { return loss_at(std::vector<float>(x.begin(), x.end())); }, zv,
      g.dz, "d/d embeddings", {.step = 1e-2, .rtol = 2e-2, .atol = 2e-2, .samples = 20});

  // d/dW with ẑ inside (−1, 1): σ = 10 gives ẑ = 0.333·(‖z‖ − 10)/10.
  head.running_std.value().upload(std::vector<float>{10.f});
  const Grads g2 = tape_gradients(head, Tensor::from(dev, Shape{b, d}, zv), lab, weights);
  const Tensor z_fixed = Tensor::from(dev, Shape{b, d}, zv);
  test::expect_gradient_matches(
      [&](std::span<const float> x) {
        head.weight.value().upload(x);
        const double l = test::weighted_sum(logits_of(t, head, z_fixed, lab), wts);
        head.weight.value().upload(w0);
        return l;
      },
      w0, g2.dw, "d/d W", {.step = 1e-3, .rtol = 2e-2, .atol = 2e-2, .samples = 15});
}

TEST(AdaFaceHead, BadInputsAreClearErrors) {
  Device& dev = test::device();
  AdaFaceHead head(dev, 4, 3, 1);
  Stream s(dev);
  Tape t(s);
  const Var z(Tensor::from(dev, {2, 4}, test::random_floats(8, 83)));
  const Var one(Tensor::from(dev, {1, 4}, test::random_floats(4, 84)));
  EXPECT_THROW(head.forward(t, Var(Tensor::from(dev, {2, 5}, test::random_floats(10, 1))),
                            labels_tensor(dev, {0, 1})),
               InvalidArgument);
  EXPECT_THROW(head.forward(t, z, labels_tensor(dev, {0, 1, 2})), InvalidArgument);
  EXPECT_THROW(head.forward(t, z, Tensor::from(dev, {2}, std::vector<float>{0, 1})),
               InvalidArgument);
  EXPECT_THROW(head.forward(t, z, Tensor{}), InvalidArgument);
  try {  // one embedding: no unbiased std in training mode
    head.forward(t, one, labels_tensor(dev, {0}));
    ADD_FAILURE() << "a batch of one trained";
  } catch (const InvalidArgument& e) {
    EXPECT_NE(std::string(e.what()).find("at least 2"), std::string::npos) << e.what();
  }
  head.eval();
  EXPECT_NO_THROW(head.forward(t, one, labels_tensor(dev, {0})));
  AdaFaceOptions bad;
  bad.m = -0.1f;
  EXPECT_THROW(AdaFaceHead(dev, 4, 3, 1, bad), InvalidArgument);
  EXPECT_THROW(AdaFaceHead(dev, 0, 3, 1), InvalidArgument);
  // A label outside [0, C) gives a NaN row (documented), not a crash.
  t.set_recording(false);
  const auto y = logits_of(t, head, z.value(), labels_tensor(dev, {0, 7}));
  EXPECT_FALSE(std::isnan(y[0]));
  EXPECT_TRUE(std::isnan(y[3]));
}

// ---- training: separable clusters -----------------------------------------------------

struct Clusters {
  Tensor x, labels;
  Labels host_labels;
};

Clusters cluster_batch(const Device& dev, const std::vector<float>& centres, std::size_t per_class,
                       std::size_t classes, std::size_t dim, std::uint32_t seed) {
  std::mt19937 rng(seed);
  std::normal_distribution<float> noise(0.f, 0.4f);
  std::vector<float> x;
  Labels labels;
  for (std::size_t i = 0; i < per_class; ++i) {
    for (std::size_t c = 0; c < classes; ++c) {
      for (std::size_t k = 0; k < dim; ++k) x.push_back(centres[c * dim + k] + noise(rng));
      labels.push_back(std::int32_t(c));
    }
  }
  return {Tensor::from(dev, Shape{std::int64_t(labels.size()), std::int64_t(dim)}, x),
          labels_tensor(dev, labels), labels};
}

TEST(AdaFaceHead, TrainingOnSeparableClustersLowersTheLoss) {
  Device& dev = test::device();
  const std::uint32_t seed = 85;
  SCOPED_TRACE("seed " + std::to_string(seed));
  const std::size_t classes = 4, dim = 8;
  const auto centres = test::random_floats(classes * dim, seed, -2.f, 2.f);
  Linear embed(dev, int(dim), int(dim), true, seed + 1);
  AdaFaceHead head(dev, int(dim), int(classes), seed + 2);
  NamedVars params = embed.named_parameters();
  for (auto& p : head.named_parameters()) params.push_back(p);
  Adam opt(params, {.lr = 2e-2f});
  std::vector<float> losses;
  for (std::uint32_t step = 0; step < 40; ++step) {
    const Clusters batch = cluster_batch(dev, centres, 8, classes, dim, seed + 100 + step);
    Stream s(dev);
    Tape t(s);
    opt.zero_grad();
    const Var logits = head.forward(t, embed.forward(t, Var(batch.x)), batch.labels);
    const Var loss = cross_entropy(t, logits, batch.labels);
    t.backward(loss);
    opt.step(s);
    s.run();
    losses.push_back(loss.value().download()[0]);
  }
  // Seen here: 42 → ~0.1 (the margin makes the first loss large: s·m ≈ 26).
  const double first = (losses[0] + losses[1]) / 2;
  const double last = (losses[35] + losses[36] + losses[37] + losses[38] + losses[39]) / 5;
  EXPECT_LT(last, 0.1 * first) << "loss " << first << " → " << last;
  // Held-out accuracy of the plain cosine classifier.
  head.eval();
  const Clusters test_batch = cluster_batch(dev, centres, 16, classes, dim, seed + 999);
  Stream s(dev);
  Tape t(s, false);
  const Var cos = head.cosine(t, embed.forward(t, Var(test_batch.x)));
  s.run();
  const auto cv = cos.value().download();
  std::size_t correct = 0;
  for (std::size_t i = 0; i < test_batch.host_labels.size(); ++i) {
    const auto row = cv.begin() + std::ptrdiff_t(i * classes);
    correct += std::size_t(std::max_element(row, row + std::ptrdiff_t(classes)) - row) ==
               std::size_t(test_batch.host_labels[i]);
  }
  EXPECT_GE(double(correct) / double(test_batch.host_labels.size()), 0.95);
}

// ---- parity with the official PyTorch head ---------------------------------------------

// Made by `tools/adaface_torch.py fixture` (PyTorch, float64, the official
// head's arithmetic): a kernel W [16, 5], the running statistics to start
// from, and 3 batches of 6 embeddings (norms 1.5 to 120: scalers clipped at
// both ends and inside, one label angle clipped at eps, one cosine clamped)
// run one after the other in training mode, with the logits, the
// cross-entropy loss, its gradients and the statistics after each call.
TEST(AdaFaceHead, MatchesTheOfficialPyTorchHead) {
  Device& dev = test::device();
  const char* fixture = VKJR2_ADAFACE_FIXTURE;
  const SafetensorsFile f = read_safetensors(fixture);
  const auto tensor = [&](const std::string& name, std::int64_t call = -1) {
    const SafetensorsRecord& r = f.at(name);
    std::vector<float> v = r.to_float();
    if (call < 0) return v;
    const auto per_call = v.size() / std::size_t(r.shape.at(0));
    return std::vector<float>(v.begin() + std::ptrdiff_t(std::size_t(call) * per_call),
                              v.begin() + std::ptrdiff_t(std::size_t(call + 1) * per_call));
  };
  const auto& zs = f.at("embeddings").shape;  // [calls, B, D]
  ASSERT_EQ(zs.size(), 3u);
  const std::int64_t calls = zs[0], b = zs[1], d = zs[2], c = f.at("kernel").shape.at(1);
  AdaFaceHead head(dev, int(d), int(c), 1);
  const AdaFaceOptions& o = head.options;  // the defaults are the paper's, as in the fixture
  for (const auto& [key, value] : std::vector<std::pair<std::string, float>>{
           {"m", o.m}, {"h", o.h}, {"s", o.s}, {"eps", o.eps}, {"t_alpha", o.alpha}}) {
    EXPECT_EQ(std::stof(f.metadata.at(key)), value) << key << " differs from the fixture's";
  }
  head.weight.set_value(Tensor::from(dev, Shape{d, c}, tensor("kernel")));
  head.running_mean.set_value(Tensor::from(dev, Shape{1}, tensor("batch_mean_init")));
  head.running_std.set_value(Tensor::from(dev, Shape{1}, tensor("batch_std_init")));
  ASSERT_TRUE(head.training());
  const std::vector<std::int32_t> all_labels = f.at("labels").as_i32();
  for (std::int64_t call = 0; call < calls; ++call) {
    SCOPED_TRACE("call " + std::to_string(call));
    const Labels labels(all_labels.begin() + call * b, all_labels.begin() + (call + 1) * b);
    const Tensor lab = labels_tensor(dev, labels);
    Stream s(dev);
    Tape t(s);
    head.zero_grad();
    const Var z(Tensor::from(dev, Shape{b, d}, tensor("embeddings", call)), true);
    const Var logits = head.forward(t, z, lab);
    const Var loss = cross_entropy(t, logits, lab);
    t.backward(loss);
    s.run();
    // Errors as fractions of the largest |value| of each quantity, measured
    // on lavapipe over the 3 calls: logits 1.6e-7, loss 1.2e-7, d embeddings
    // 9.1e-7 (in call 2's clamped row: norm 1.5 and 0.08 rad from the
    // winning class's centre, where the cosine's gradient (w − cos·u)/‖z‖ is
    // a difference of nearly equal vectors), d kernel 2.6e-7, batch_mean
    // 2.4e-7, batch_std 1.2e-7; PyTorch float32 gives at most 6.9e-7. Bound
    // 1e-5 for all: passing a gradient through the clamped cosine would be
    // off by 0.09, through the clipped angle by 3e-4 (d kernel).
    constexpr double kTol = 1e-5;
    const auto expect_close = [&](const char* name, const std::vector<float>& got) {
      const std::vector<float> want = tensor(name, call);
      double peak = 0;
      for (const float v : want) peak = std::max(peak, double(std::fabs(v)));
      test::expect_all_close(name, got, want, {0, kTol * peak});
    };
    expect_close("logits", logits.value().download());
    expect_close("loss", loss.value().download());
    expect_close("d_embeddings", z.grad().download());
    expect_close("d_kernel", head.weight.grad().download());
    expect_close("batch_mean", head.running_mean.value().download());
    expect_close("batch_std", head.running_std.value().download());
  }
}

}  // namespace
}  // namespace vkjr2::nets
