// Every differentiable op: the tape's gradient against central finite
// differences of the op's forward, on random shapes, for every input.
#include <vkjr2/nets/ops.hpp>

#include <gtest/gtest.h>

#include <functional>

#include "support/gradcheck.hpp"
#include "support/test_device.hpp"

namespace vkjr2::nets {
namespace {

using Build = std::function<Var(Tape&, const std::vector<Var>&)>;

struct Input {
  Shape shape;
  float lo = -1.f, hi = 1.f;
};

// L = Σ w ⊙ f(inputs); checks dL/d input_i for every input.
void check_gradients(const std::string& what, const std::vector<Input>& inputs, const Build& f,
                     std::uint32_t seed, test::GradCheckOptions o = {}) {
  SCOPED_TRACE(what + ", seed " + std::to_string(seed));
  Device& dev = test::device();
  std::vector<std::vector<float>> host;
  std::vector<Var> vars;
  for (std::size_t i = 0; i < inputs.size(); ++i) {
    host.push_back(test::random_floats(std::size_t(inputs[i].shape.numel()),
                                       seed + std::uint32_t(i), inputs[i].lo, inputs[i].hi));
    vars.emplace_back(Tensor::from(dev, inputs[i].shape, host.back()), true);
  }
  Stream stream(dev);
  Tape tape(stream);
  const Var y = f(tape, vars);
  const std::vector<float> w = test::random_floats(std::size_t(y.numel()), seed + 100);
  const Var loss = sum_all(tape, mul(tape, y, Var(Tensor::from(dev, y.shape(), w))));
  tape.backward(loss);
  stream.run();

  for (std::size_t i = 0; i < inputs.size(); ++i) {
    ASSERT_TRUE(vars[i].has_grad()) << what << ": input " << i << " got no gradient";
    const std::vector<float> analytic = vars[i].grad().download();
    const auto forward = [&](std::span<const float> x) {
      std::vector<Var> probe;
      for (std::size_t j = 0; j < inputs.size(); ++j) {
        probe.emplace_back(Tensor::from(dev, inputs[j].shape, j == i ? x : host[j]), false);
      }
      Stream s(dev);
      Tape inference(s, false);
      const Var out = f(inference, probe);
      s.run();
      return test::weighted_sum(out.value().download(), w);
    };
    test::expect_gradient_matches(forward, host[i], analytic, what + " d/input" + std::to_string(i),
                                  o);
  }
}

TEST(NetsOps, ElementwiseAndChannel) {
  const Shape s{2, 3, 5, 7};
  check_gradients(
      "add", {{s}, {s}}, [](Tape& t, auto& v) { return add(t, v[0], v[1]); }, 1);
  check_gradients(
      "sub", {{s}, {s}}, [](Tape& t, auto& v) { return sub(t, v[0], v[1]); }, 2);
  check_gradients(
      "mul", {{s}, {s}}, [](Tape& t, auto& v) { return mul(t, v[0], v[1]); }, 3);
  check_gradients(
      "scale_shift", {{s}}, [](Tape& t, auto& v) { return scale_shift(t, v[0], -1.5f, 0.25f); }, 4);
  check_gradients(
      "exp", {{s}}, [](Tape& t, auto& v) { return exp(t, v[0]); }, 5);
  check_gradients(
      "log", {{s, 0.5f, 2.f}}, [](Tape& t, auto& v) { return log(t, v[0]); }, 6);
  check_gradients(
      "add_channel", {{s}, {Shape{3}}}, [](Tape& t, auto& v) { return add_channel(t, v[0], v[1]); },
      7);
  check_gradients(
      "mul_channel", {{s}, {Shape{3}}}, [](Tape& t, auto& v) { return mul_channel(t, v[0], v[1]); },
      8);
  check_gradients(
      "sum_channels", {{s}}, [](Tape& t, auto& v) { return sum_channels(t, v[0]); }, 9);
  check_gradients(
      "channel_affine", {{s}, {Shape{3}}, {Shape{3}}},
      [](Tape& t, auto& v) { return channel_affine(t, v[0], v[1], v[2]); }, 10);
  check_gradients(
      "mul_sample_channel", {{s}, {Shape{2, 3, 1, 1}}},
      [](Tape& t, auto& v) { return mul_sample_channel(t, v[0], v[1]); }, 18);
}

TEST(NetsOps, NormGateAndShuffle) {
  const Shape s{2, 6, 5, 4};
  check_gradients("layer_norm_channels", {{s}, {Shape{6}, 0.5f, 1.5f}, {Shape{6}}},
                  [](Tape& t, auto& v) { return layer_norm_channels(t, v[0], v[1], v[2]); }, 19,
                  {.step = 1e-2});
  check_gradients(
      "simple_gate", {{s}}, [](Tape& t, auto& v) { return simple_gate(t, v[0]); }, 20);
  check_gradients(
      "pixel_shuffle", {{Shape{2, 8, 3, 5}}},
      [](Tape& t, auto& v) { return pixel_shuffle(t, v[0], 2); }, 21);
  check_gradients(
      "pixel_unshuffle", {{Shape{2, 2, 6, 4}}},
      [](Tape& t, auto& v) { return pixel_unshuffle(t, v[0], 2); }, 22);
}

TEST(NetsOps, Activations) {
  const Shape s{3, 2, 4, 9};
  // Inputs kept away from the kinks at 0 by the finite-difference step.
  test::GradCheckOptions o;
  o.step = 1e-3;
  check_gradients(
      "relu", {{s}}, [](Tape& t, auto& v) { return relu(t, v[0]); }, 11, o);
  check_gradients(
      "leaky_relu", {{s}}, [](Tape& t, auto& v) { return leaky_relu(t, v[0], 0.1f); }, 12, o);
  check_gradients(
      "prelu", {{s}, {Shape{2}}}, [](Tape& t, auto& v) { return prelu(t, v[0], v[1]); }, 13, o);
  check_gradients(
      "sigmoid", {{s}}, [](Tape& t, auto& v) { return sigmoid(t, v[0]); }, 14);
  check_gradients(
      "tanh", {{s}}, [](Tape& t, auto& v) { return tanh(t, v[0]); }, 15);
  check_gradients(
      "softmax", {{Shape{5, 11}}}, [](Tape& t, auto& v) { return softmax(t, v[0]); }, 16);
  check_gradients(
      "log_softmax", {{Shape{5, 11}}}, [](Tape& t, auto& v) { return log_softmax(t, v[0]); }, 17);
}

TEST(NetsOps, ConvolutionWithFusedActivationAndBias) {
  kernels::Conv2dParams p;
  p.stride_y = 2;
  p.stride_x = 1;
  p.pad = {0, 1, 1, 1};
  p.activation = kernels::Activation::leaky_relu;
  p.leaky_slope = 0.1f;
  test::GradCheckOptions o;
  o.step = 1e-3;
  check_gradients(
      "conv2d leaky", {{Shape{2, 3, 9, 7}}, {Shape{4, 3, 3, 3}}, {Shape{4}}},
      [p](Tape& t, auto& v) { return conv2d(t, v[0], v[1], v[2], p); }, 21, o);
  kernels::Conv2dParams dw;
  dw.groups = 4;
  dw.pad = {1, 1, 1, 1};
  check_gradients(
      "conv2d depthwise, no bias", {{Shape{1, 4, 6, 5}}, {Shape{4, 1, 3, 3}}},
      [dw](Tape& t, auto& v) { return conv2d(t, v[0], v[1], Var(), dw); }, 22, o);
  // A residual in the epilogue with fewer channels than y (4 of 6; batch 2:
  // its gradient is a channel slice of each image's). No activation: with
  // 180 outputs per weight, central differences would cross its kink.
  kernels::Conv2dParams rp;
  rp.pad = {1, 1, 1, 1};
  check_gradients(
      "conv2d with a residual",
      {{Shape{2, 3, 5, 6}}, {Shape{6, 3, 3, 3}}, {Shape{6}}, {Shape{2, 4, 5, 6}}},
      [rp](Tape& t, auto& v) { return conv2d(t, v[0], v[1], v[2], rp, nullptr, v[3]); }, 23, o);
}

TEST(NetsOps, LinearPoolingResizeLayout) {
  check_gradients(
      "linear", {{Shape{5, 7}}, {Shape{7, 3}}, {Shape{3}}},
      [](Tape& t, auto& v) { return linear(t, v[0], v[1], v[2]); }, 31);
  const Shape s{2, 3, 7, 6};
  check_gradients(
      "max_pool2d", {{s}},
      [](Tape& t, auto& v) { return max_pool2d(t, v[0], kernels::pool_valid(3, 3, 2, 2)); }, 32);
  check_gradients(
      "avg_pool2d same", {{s}},
      [](Tape& t, auto& v) { return avg_pool2d(t, v[0], kernels::pool_same(2, 2, 2, 2, 7, 6)); },
      33);
  check_gradients(
      "global_avg_pool", {{s}}, [](Tape& t, auto& v) { return global_avg_pool(t, v[0]); }, 34);
  check_gradients(
      "resize legacy", {{s}},
      [](Tape& t, auto& v) { return resize(t, v[0], kernels::ResizeMode::bilinear_legacy, 11, 4); },
      35);
  check_gradients(
      "pad", {{s}},
      [](Tape& t, auto& v) {
        return pad(t, v[0], kernels::Pad2d{1, 0, 2, 3}, 0.5f);
      },
      36);
  check_gradients(
      "concat", {{s}, {Shape{2, 2, 7, 6}}},
      [](Tape& t, auto& v) {
        return concat_channels(t, std::vector<Var>{v[0], v[1]});
      },
      37);
  check_gradients(
      "slice", {{s}},
      [](Tape& t, auto& v) {
        return slice(t, v[0], kernels::SliceStart{1, 2, 1}, Shape{2, 2, 4, 5});
      },
      38);
  check_gradients(
      "reshape", {{s}},
      [](Tape& t, auto& v) {
        return reshape(t, v[0], Shape{6, 42});
      },
      39);
}

TEST(NetsOps, GeometryReductionsLosses) {
  test::GradCheckOptions o;
  o.step = 1e-3;
  check_gradients(
      "grid_sample", {{Shape{1, 2, 6, 7}}, {Shape{1, 4, 5, 2}, -0.9f, 0.9f}},
      [](Tape& t, auto& v) { return grid_sample(t, v[0], v[1]); }, 41, o);
  check_gradients(
      "affine_grid", {{Shape{2, 2, 3}}},
      [](Tape& t, auto& v) { return affine_grid(t, v[0], 4, 5, false); }, 42);
  const Shape s{4, 9};
  check_gradients(
      "sum_all", {{s}}, [](Tape& t, auto& v) { return sum_all(t, v[0]); }, 43);
  check_gradients(
      "mean_all", {{s}}, [](Tape& t, auto& v) { return mean_all(t, v[0]); }, 44);
  check_gradients(
      "sum_rows", {{s}}, [](Tape& t, auto& v) { return sum_rows(t, v[0]); }, 45);
  check_gradients(
      "mean_rows", {{s}}, [](Tape& t, auto& v) { return mean_rows(t, v[0]); }, 46);
  check_gradients(
      "l2norm_rows", {{s}}, [](Tape& t, auto& v) { return l2norm_rows(t, v[0]); }, 47);
  check_gradients(
      "l1", {{s}, {s}}, [](Tape& t, auto& v) { return l1_loss(t, v[0], v[1]); }, 48, o);
  check_gradients(
      "mse", {{s}, {s}}, [](Tape& t, auto& v) { return mse_loss(t, v[0], v[1]); }, 49);
  check_gradients(
      "charbonnier", {{s}, {s}},
      [](Tape& t, auto& v) { return charbonnier_loss(t, v[0], v[1], 0.1f); }, 50);
  check_gradients(
      "cosine", {{s}, {s}}, [](Tape& t, auto& v) { return cosine_similarity(t, v[0], v[1]); }, 51);
  const Tensor labels = [] {
    const std::vector<std::int32_t> l{0, 3, 8, 2};
    Tensor t = Tensor::empty(test::device(), Shape{4}, DType::i32);
    t.upload_bytes(l.data(), l.size() * sizeof(std::int32_t));
    return t;
  }();
  check_gradients(
      "cross_entropy", {{s}}, [labels](Tape& t, auto& v) { return cross_entropy(t, v[0], labels); },
      52);
}

}  // namespace
}  // namespace vkjr2::nets
