// Differentiable ops: each runs its forward kernel on the tape's stream and,
// when the tape records and an input needs a gradient, records the backward
// (nets/autograd.hpp). Shapes and semantics are those of the kernels
// (kernels/*.hpp): NCHW images, f32.
#pragma once

#include <vkjr2/kernels/conv2d.hpp>
#include <vkjr2/kernels/grid_sample.hpp>
#include <vkjr2/kernels/layout.hpp>
#include <vkjr2/kernels/pool.hpp>
#include <vkjr2/kernels/resize.hpp>
#include <vkjr2/nets/autograd.hpp>

#include <cstdint>
#include <memory>
#include <mutex>
#include <span>
#include <vector>

namespace vkjr2::nets {

// ---- elementwise (same shape) -------------------------------------------------
Var add(Tape& t, const Var& a, const Var& b);
Var sub(Tape& t, const Var& a, const Var& b);
Var mul(Tape& t, const Var& a, const Var& b);
// scale · x + shift (scalars).
Var scale_shift(Tape& t, const Var& x, float scale, float shift = 0.f);
Var exp(Tape& t, const Var& x);
Var log(Tape& t, const Var& x);

// ---- per-channel broadcasts over [N, C, spatial...] ---------------------------
Var add_channel(Tape& t, const Var& x, const Var& v);  // x + v[c]
Var mul_channel(Tape& t, const Var& x, const Var& v);  // x · v[c]
// x [N, C, H, W] · s[n, c] with s [N, C, 1, 1] (or [N, C]): a per-sample
// channel scale (NAFNet's channel attention).
Var mul_sample_channel(Tape& t, const Var& x, const Var& s);
// [C]: Σ over n and the spatial axes.
Var sum_channels(Tape& t, const Var& x);
// x · scale[c] + bias[c] (frozen batch norm / face-api's scale layer).
Var channel_affine(Tape& t, const Var& x, const Var& scale, const Var& bias);

// ---- normalization and gating -----------------------------------------------------
// NAFNet's LayerNorm2d over the channels of each pixel (kernels/norm.hpp):
// gamma · x̂ + beta, gamma and beta [C].
Var layer_norm_channels(Tape& t, const Var& x, const Var& gamma, const Var& beta,
                        float eps = 1e-6f);
// [N, 2C, ...] → [N, C, ...]: the first half of the channels times the second.
Var simple_gate(Tape& t, const Var& x);

// ---- activations ----------------------------------------------------------------
Var relu(Tape& t, const Var& x);
Var leaky_relu(Tape& t, const Var& x, float slope);
Var prelu(Tape& t, const Var& x, const Var& slope);
Var sigmoid(Tape& t, const Var& x);
Var tanh(Tape& t, const Var& x);
Var softmax(Tape& t, const Var& x);      // over the last axis
Var log_softmax(Tape& t, const Var& x);  // over the last axis

// ---- layers' compute ------------------------------------------------------------
// A layer's convolution plans (kernels::Conv2dPlan): one per input shape and
// device, made on first use, each holding the weight packed for its variant
// (packed again only after the weight changed: another Var, or a new
// Var::version(): optimizer steps, set_value, checkpoint loads). A layer
// holds one per weight; thread-safe.
class ConvPlans {
 public:
  ConvPlans();
  ~ConvPlans();
  ConvPlans(const ConvPlans&) = delete;
  ConvPlans& operator=(const ConvPlans&) = delete;

  // The plan for x of shape x, with weight packed on `stream` when stale.
  kernels::Conv2dPlan get(Stream& stream, const Shape& x, const Var& weight,
                          const kernels::Conv2dParams& p) const;
  // The layout in which conv2d() reads x of shape x with no padding pass:
  // the plan's input layout, or plain when the weight or bias needs a
  // gradient (the backward reads x plain). The producer of x passes it as
  // its `out`.
  kernels::PlaneLayout input_layout(const Tape& t, const Shape& x, const Var& weight,
                                    const Var& bias, const kernels::Conv2dParams& p) const;

 private:
  struct Entry;
  kernels::Conv2dPlan& entry(const Device& device, const Shape& x, const Shape& weight,
                             const kernels::Conv2dParams& p, Entry** found) const;
  mutable std::vector<Entry> entries_;
  mutable std::unique_ptr<std::mutex> mutex_;
};

// act(conv(relu?(x), weight) + bias + residual); weight OIHW; bias and
// residual may be undefined (p.relu_input: the ReLU on x, fused into the
// depthwise and direct variants when nothing needs a gradient). plans: the
// layer's plans (nullptr: a plan and packed weight per call). residual:
// [N, Cr, Hout, Wout], Cr <= Cout (the channels past Cr get none: a
// shortcut zero-padded in channels), added in the conv's epilogue (a
// residual block's add and ReLU in one dispatch). x and residual may be
// padded Vars. out: the layout of the output's consumer
// (ConvPlans::input_layout): the output is written in it when it needs no
// gradient and the variant writes padded planes, else plain.
Var conv2d(Tape& t, const Var& x, const Var& weight, const Var& bias,
           const kernels::Conv2dParams& p, const ConvPlans* plans = nullptr,
           const Var& residual = Var(), const kernels::PlaneLayout& out = {});
// The value of x as a plain tensor (a copy of the interior when x is padded).
Tensor plain(Tape& t, const Var& x);
// x [M, K] · weight [K, N] (+ bias [N] when defined).
Var linear(Tape& t, const Var& x, const Var& weight, const Var& bias);
// out: as conv2d's (the output written into its consumer's padded input
// when it needs no gradient).
Var max_pool2d(Tape& t, const Var& x, const kernels::Pool2d& p,
               const kernels::PlaneLayout& out = {});
Var avg_pool2d(Tape& t, const Var& x, const kernels::Pool2d& p, bool count_include_pad = false);
Var global_avg_pool(Tape& t, const Var& x);  // [N, C, 1, 1]
Var resize(Tape& t, const Var& x, kernels::ResizeMode mode, std::int64_t out_h, std::int64_t out_w);
Var pad(Tape& t, const Var& x, const kernels::Pad2d& p, float value = 0.f);
// [N, C·r², H, W] → [N, C, H·r, W·r] (PyTorch's PixelShuffle) and back.
Var pixel_shuffle(Tape& t, const Var& x, int r);
Var pixel_unshuffle(Tape& t, const Var& x, int r);
Var concat_channels(Tape& t, std::span<const Var> xs);
Var slice(Tape& t, const Var& x, const kernels::SliceStart& start, const Shape& shape);
// Same memory under another shape; the gradient is reshaped back.
Var reshape(Tape& t, const Var& x, const Shape& shape);

// ---- geometry --------------------------------------------------------------------
Var grid_sample(Tape& t, const Var& input, const Var& grid, kernels::GridSampleOptions o = {});
// grid [N, H, W, 2] from theta [N, 2, 3].
Var affine_grid(Tape& t, const Var& theta, std::int64_t height, std::int64_t width,
                bool align_corners);

// ---- reductions (outputs of one element, or one per row of the last axis) ----------
Var sum_all(Tape& t, const Var& x);
Var mean_all(Tape& t, const Var& x);
Var sum_rows(Tape& t, const Var& x);     // [rows]
Var mean_rows(Tape& t, const Var& x);    // [rows]
Var l2norm_rows(Tape& t, const Var& x);  // [rows]

// ---- losses (mean over elements, one-element output) ------------------------------
Var l1_loss(Tape& t, const Var& pred, const Var& target);
Var mse_loss(Tape& t, const Var& pred, const Var& target);
Var charbonnier_loss(Tape& t, const Var& pred, const Var& target, float eps = 1e-3f);
// Per row of a, b [rows, K]: cosine similarity, [rows].
Var cosine_similarity(Tape& t, const Var& a, const Var& b);
// logits [rows, K], labels i32 [rows] (not differentiated).
Var cross_entropy(Tape& t, const Var& logits, const Tensor& labels);

}  // namespace vkjr2::nets
