#include <vkjr2/kernels/adaface.hpp>
#include <vkjr2/nets/adaface.hpp>
#include <vkjr2/nets/layers.hpp>
#include <vkjr2/runtime/error.hpp>

#include <cmath>
#include <string>
#include <utility>
#include <vector>

namespace vkjr2::nets {
namespace {

constexpr const char* kOp = "nets::AdaFaceHead";

// W [D, C] uniform(−1, 1) with unit-norm columns (the official
// uniform_(−1, 1).renorm_(2, 1, 1e-5).mul_(1e5)).
std::vector<float> unit_columns(int rows, int cols, std::uint32_t seed) {
  const auto r_n = std::size_t(rows), c_n = std::size_t(cols);
  std::vector<float> w = uniform_init(r_n * c_n, 1.f, seed);
  for (std::size_t c = 0; c < c_n; ++c) {
    double ss = 0;
    for (std::size_t r = 0; r < r_n; ++r) ss += double(w[r * c_n + c]) * w[r * c_n + c];
    const double inv = ss > 0 ? 1.0 / std::sqrt(ss) : 0.0;
    for (std::size_t r = 0; r < r_n; ++r) w[r * c_n + c] = float(w[r * c_n + c] * inv);
  }
  return w;
}

// 1 / x^p for p > 0, differentiable: exp(−p·log x) (as BatchNorm2d does).
Var inverse_power(Tape& t, const Var& x, float p) { return exp(t, scale_shift(t, log(t, x), -p)); }

}  // namespace

AdaFaceHead::AdaFaceHead(const Device& device, int embedding_dim, int classes, std::uint32_t seed,
                         const AdaFaceOptions& o)
    : options(o) {
  if (embedding_dim <= 0 || classes <= 0) {
    throw InvalidArgument(kOp,
                          "embedding_dim = " + std::to_string(embedding_dim) +
                              " and classes = " + std::to_string(classes) + " must be > 0",
                          "pass the embedder's output size and the number of identities");
  }
  kernels::check_adaface_params(o, kOp);
  weight = register_parameter("kernel", Tensor::from(device, Shape{embedding_dim, classes},
                                                     unit_columns(embedding_dim, classes, seed)));
  running_mean =
      register_buffer("batch_mean", Tensor::from(device, Shape{1}, std::vector<float>{20.f}));
  running_std =
      register_buffer("batch_std", Tensor::from(device, Shape{1}, std::vector<float>{100.f}));
}

namespace {

struct CosineAndNorms {
  Var cos;    // [B, C]
  Var norms;  // [B], ‖z_b‖
};

// Returns B.
std::int64_t check_embeddings(const Var& embeddings, const Var& weight) {
  if (!embeddings.defined()) {
    throw InvalidArgument(kOp, "embeddings are undefined", "pass a [B, D] f32 Var");
  }
  const Shape& s = embeddings.shape();
  if (s.rank() != 2 || s[0] < 1 || s[1] != weight.shape()[0]) {
    throw InvalidArgument(kOp,
                          "embeddings have shape " + s.str() + "; expected [B, " +
                              std::to_string(weight.shape()[0]) + "] with B ≥ 1",
                          "pass one embedding of the head's dimension per row");
  }
  return s[0];
}

CosineAndNorms cosine_and_norms(Tape& t, const Var& embeddings, const Var& weight) {
  const std::int64_t b = check_embeddings(embeddings, weight), c = weight.shape()[1];
  // cos = (z·W) / ‖z_b‖ / ‖W_j‖: scaling the [B, C] product is cheaper than
  // normalizing W [D, C], and the same function.
  const Var raw = linear(t, embeddings, weight, Var{});
  const Var inv_w = inverse_power(t, sum_channels(t, mul(t, weight, weight)), 0.5f);  // [C]
  const Var norms = l2norm_rows(t, embeddings);                                       // [B]
  const Var by_w = mul_channel(t, raw, inv_w);
  const Var by_z = mul_channel(t, reshape(t, by_w, Shape{1, b, c}), inverse_power(t, norms, 1.f));
  return {reshape(t, by_z, Shape{b, c}), norms};
}

}  // namespace

Var AdaFaceHead::cosine(Tape& t, const Var& embeddings) const {
  return cosine_and_norms(t, embeddings, weight).cos;
}

Var AdaFaceHead::forward(Tape& t, const Var& embeddings, const Tensor& labels) const {
  const std::int64_t b = check_embeddings(embeddings, weight);
  if (training() && b < 2) {
    throw InvalidArgument(
        kOp,
        "training mode needs a batch of at least 2 embeddings, got " + embeddings.shape().str(),
        "use a larger batch (the norm statistics need an unbiased std), or "
        "eval mode");
  }
  if (!labels.defined() || labels.dtype() != DType::i32 || !(labels.shape() == Shape{b})) {
    throw InvalidArgument(
        kOp,
        "labels must be i32 [" + std::to_string(b) + "] (one class per embedding)" +
            (labels.defined()
                 ? ", got " + std::string(dtype_name(labels.dtype())) + " " + labels.shape().str()
                 : ", got an undefined tensor"),
        "pass the class index of each embedding as an i32 tensor");
  }
  const CosineAndNorms cn = cosine_and_norms(t, embeddings, weight);
  const Var& cos = cn.cos;
  Stream& st = t.stream();
  const Device device = embeddings.value().device();
  // ẑ from the norms' values: no gradient flows through it (the paper detaches it).
  Tensor scaler = Tensor::empty(device, Shape{b});
  kernels::adaface_scaler(st, cn.norms.value(), running_mean.value(), running_std.value(),
                          training(), options, scaler);
  Tensor logits = Tensor::empty(device, cos.shape());
  kernels::adaface_margin(st, cos.value(), labels, scaler, options, logits);

  // Recorded as ops.cpp's finish() does: the backward runs when a gradient reaches the output.
  const bool grad = t.needs_grad({&cos});
  Var out = t.output(logits, grad);
  if (grad) {
    t.record([out, cos, labels, scaler, o = options](Tape& tape) {
      const Tensor& dy = Tape::grad_of(out);
      if (!dy.defined()) return;
      GradSlot g = tape.slot(cos);
      kernels::adaface_margin_backward(tape.stream(), cos.value(), labels, scaler, dy, o, g.target);
      tape.commit(g);
    });
  }
  return out;
}

}  // namespace vkjr2::nets
