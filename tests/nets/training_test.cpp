// End-to-end training on the device: an MLP (regression, Adam + warmup-cosine)
// and a small CNN with batch norm (classification, SGD momentum) drive their
// loss down, and a run resumed from a checkpoint ends bit-identical to an
// uninterrupted one.
#include <vkjr2/nets/checkpoint.hpp>
#include <vkjr2/nets/layers.hpp>
#include <vkjr2/nets/optimizer.hpp>

#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <random>

#include "support/test_device.hpp"

namespace vkjr2::nets {
namespace {

// Flat index of an int index expression (test shapes are small).
std::size_t flat(std::int64_t i) { return static_cast<std::size_t>(i); }

// ---- the MLP: y = sin(2 x0) + x1² from 2-D inputs -----------------------------------

class Mlp : public Module {
 public:
  explicit Mlp(const Device& d)
      : l1(register_module("l1", std::make_unique<Linear>(d, 2, 32, true, 1))),
        l2(register_module("l2", std::make_unique<Linear>(d, 32, 32, true, 2))),
        l3(register_module("l3", std::make_unique<Linear>(d, 32, 1, true, 3))) {}
  Var forward(Tape& t, const Var& x) const {
    return l3.forward(t, tanh(t, l2.forward(t, tanh(t, l1.forward(t, x)))));
  }
  Linear& l1;
  Linear& l2;
  Linear& l3;
};

struct Batch {
  Var x, y;
};

Batch regression_batch(const Device& d, std::uint32_t seed) {
  std::mt19937 rng(seed);
  std::vector<float> x(64 * 2), y(64);
  for (int i = 0; i < 64; ++i) {
    x[2 * i] = float(rng() % 2001) / 1000.f - 1.f;
    x[2 * i + 1] = float(rng() % 2001) / 1000.f - 1.f;
    y[i] = std::sin(2.f * x[2 * i]) + x[2 * i + 1] * x[2 * i + 1];
  }
  return {Var(Tensor::from(d, Shape{64, 2}, x)), Var(Tensor::from(d, Shape{64, 1}, y))};
}

// ---- the CNN: bars (horizontal vs vertical) in noise, 16×16 -------------------------

class SmallCnn : public Module {
 public:
  explicit SmallCnn(const Device& d)
      : c1(register_module("c1", std::make_unique<Conv2d>(d, 1, 8, 3, 3, pad1(), false, 11))),
        bn1(register_module("bn1", std::make_unique<BatchNorm2d>(d, 8))),
        c2(register_module("c2", std::make_unique<Conv2d>(d, 8, 16, 3, 3, pad1(), true, 12))),
        fc(register_module("fc", std::make_unique<Linear>(d, 16, 2, true, 13))) {}
  Var forward(Tape& t, const Var& x) const {
    Var h = relu(t, bn1.forward(t, c1.forward(t, x)));
    h = max_pool2d(t, h, kernels::pool_valid(2, 2, 2, 2));
    h = global_avg_pool(t, c2.forward(t, h));
    return fc.forward(t, reshape(t, h, Shape{h.shape()[0], 16}));
  }
  static kernels::Conv2dParams pad1() {
    kernels::Conv2dParams p;
    p.pad = {1, 1, 1, 1};
    return p;
  }
  Conv2d& c1;
  BatchNorm2d& bn1;
  Conv2d& c2;
  Linear& fc;
};

struct Images {
  Var x;
  Tensor labels;
};

Images bars_batch(const Device& d, std::uint32_t seed) {
  constexpr int n = 16, s = 16;
  std::mt19937 rng(seed);
  std::vector<float> x(std::size_t(n * s * s));
  std::vector<std::int32_t> labels(n);
  for (int i = 0; i < n; ++i) {
    labels[std::size_t(i)] = int(rng() % 2);
    const int line = int(rng() % s);
    for (int r = 0; r < s; ++r) {
      for (int c = 0; c < s; ++c) {
        const bool on = labels[std::size_t(i)] == 0 ? r == line : c == line;
        const float noise = float(rng() % 1001) / 1000.f - 0.5f;
        x[flat((i * s + r) * s + c)] = (on ? 1.f : 0.f) + 0.3f * noise;
      }
    }
  }
  Tensor l = Tensor::empty(d, Shape{n}, DType::i32);
  l.upload_bytes(labels.data(), labels.size() * sizeof(std::int32_t));
  return {Var(Tensor::from(d, Shape{n, 1, s, s}, x)), l};
}

std::vector<std::vector<float>> snapshot(const Module& m) {
  std::vector<std::vector<float>> out;
  for (const auto& [name, v] : m.named_parameters()) out.push_back(v.value().download());
  for (const auto& [name, v] : m.named_buffers()) out.push_back(v.value().download());
  return out;
}

float train_mlp_steps(Mlp& net, Adam& opt, const WarmupCosine& lr, std::uint32_t from,
                      std::uint32_t to) {
  const Device& d = test::device();
  Stream s(d);
  float last = 0.f;
  for (std::uint32_t step = from; step < to; ++step) {
    const Batch b = regression_batch(d, 1000 + step);
    Tape t(s);
    const Var loss = mse_loss(t, net.forward(t, b.x), b.y);
    opt.zero_grad();
    t.backward(loss);
    opt.set_lr(lr.at(step));
    opt.step(s);
    s.run();
    last = loss.value().download()[0];
  }
  return last;
}

// Returns the mean loss over the steps (one batch's loss is noisy).
float train_cnn_steps(SmallCnn& net, Sgd& opt, std::uint32_t from, std::uint32_t to) {
  const Device& d = test::device();
  Stream s(d);
  float total = 0.f;
  for (std::uint32_t step = from; step < to; ++step) {
    const Images b = bars_batch(d, 5000 + step);
    Tape t(s);
    const Var loss = cross_entropy(t, net.forward(t, b.x), b.labels);
    opt.zero_grad();
    t.backward(loss);
    opt.step(s);
    s.run();
    total += loss.value().download()[0];
  }
  return total / float(to - from);
}

std::filesystem::path temp_path(const char* name) {
  return std::filesystem::temp_directory_path() /
         (std::string("vkjr2_") + name + "_" + std::to_string(::getpid()) + ".safetensors");
}

TEST(NetsTraining, MlpLossFallsAndResumesBitExactly) {
  const Device& d = test::device();
  const WarmupCosine lr{3e-2f, 1e-3f, 10, 120};
  Mlp full(d);
  Adam full_opt(full.named_parameters(), {});
  const float first = train_mlp_steps(full, full_opt, lr, 0, 1);
  const float mid = train_mlp_steps(full, full_opt, lr, 1, 60);
  const auto path = temp_path("mlp");
  save_checkpoint(path, full, &full_opt);
  const float last = train_mlp_steps(full, full_opt, lr, 60, 120);
  EXPECT_LT(last, 0.1f * first) << "loss " << first << " → " << mid << " → " << last;

  Mlp resumed(d);
  Adam resumed_opt(resumed.named_parameters(), {});
  load_checkpoint(path, resumed, &resumed_opt);
  EXPECT_EQ(resumed_opt.steps(), 60u);
  train_mlp_steps(resumed, resumed_opt, lr, 60, 120);
  EXPECT_EQ(snapshot(resumed), snapshot(full)) << "resumed run differs from the uninterrupted one";
  std::filesystem::remove(path);
}

TEST(NetsTraining, CnnWithBatchNormLearnsAndResumesBitExactly) {
  const Device& d = test::device();
  SmallCnn full(d);
  Sgd full_opt(full.named_parameters(), {0.02f, 0.9f, 1e-4f});
  const float first = train_cnn_steps(full, full_opt, 0, 5);
  train_cnn_steps(full, full_opt, 5, 30);
  const auto path = temp_path("cnn");
  save_checkpoint(path, full, &full_opt, {{"note", "test"}});
  train_cnn_steps(full, full_opt, 30, 50);
  const float last = train_cnn_steps(full, full_opt, 50, 60);
  EXPECT_LT(last, 0.5f * first) << "mean cross-entropy " << first << " → " << last;

  SmallCnn resumed(d);
  Sgd resumed_opt(resumed.named_parameters(), {0.02f, 0.9f, 1e-4f});
  const auto meta = load_checkpoint(path, resumed, &resumed_opt);
  EXPECT_EQ(meta.at("note"), "test");
  train_cnn_steps(resumed, resumed_opt, 30, 60);
  EXPECT_EQ(snapshot(resumed), snapshot(full)) << "resumed run differs from the uninterrupted one";
  std::filesystem::remove(path);
}

TEST(NetsTraining, CheckpointOfAnotherNetworkIsRejected) {
  const Device& d = test::device();
  Mlp mlp(d);
  const auto path = temp_path("wrong");
  save_checkpoint(path, mlp, nullptr);
  SmallCnn cnn(d);
  try {
    load_checkpoint(path, cnn, nullptr);
    FAIL() << "expected InvalidArgument";
  } catch (const InvalidArgument& e) {
    EXPECT_NE(std::string(e.what()).find("another network"), std::string::npos) << e.what();
  }
  std::filesystem::remove(path);
}

}  // namespace
}  // namespace vkjr2::nets
