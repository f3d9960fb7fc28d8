#include <vkjr2/kernels/activation.hpp>
#include <vkjr2/kernels/basic.hpp>
#include <vkjr2/kernels/elementwise.hpp>
#include <vkjr2/kernels/loss.hpp>
#include <vkjr2/kernels/matmul.hpp>
#include <vkjr2/kernels/norm.hpp>
#include <vkjr2/kernels/reduce.hpp>
#include <vkjr2/kernels/softmax.hpp>
#include <vkjr2/nets/ops.hpp>
#include <vkjr2/runtime/error.hpp>

#include <string>
#include <utility>
#include <vector>

#include "internal/var_state.hpp"

namespace vkjr2::nets {
namespace {

namespace k = kernels;

Tensor empty_like(const Tensor& t) { return Tensor::empty(t.device(), t.shape(), t.dtype()); }
Tensor empty(const Var& like, const Shape& shape) {
  return Tensor::empty(like.value().device(), shape, DType::f32);
}

// Wraps an op's forward result; when a gradient is needed, records `step`
// (called with the tape and the output's gradient, skipped when no gradient
// reached the output).
template <class Step>
Var finish(Tape& t, Tensor value, std::initializer_list<const Var*> inputs, Step step) {
  const bool grad = t.needs_grad(inputs);
  Var out = t.output(std::move(value), grad);
  if (grad) {
    t.record([out, step = std::move(step)](Tape& tape) {
      const Tensor& dy = Tape::grad_of(out);
      if (dy.defined()) step(tape, dy);
    });
  }
  return out;
}

// Writes −src into the gradient slot of v (the target side of L1/MSE/Charbonnier).
void commit_negated(Tape& tape, const Var& v, const Tensor& src) {
  GradSlot g = tape.slot(v);
  if (!g) return;
  k::scale_shift(tape.stream(), src, -1.f, 0.f, g.target);
  tape.commit(g);
}

std::int64_t rows_of(const Var& x) { return x.numel() / x.shape()[-1]; }

}  // namespace

// ---- elementwise ------------------------------------------------------------------

Var add(Tape& t, const Var& a, const Var& b) {
  Tensor y = empty_like(a.value());
  k::add(t.stream(), a.value(), b.value(), y);
  return finish(t, y, {&a, &b}, [a, b](Tape& tape, const Tensor& dy) {
    GradSlot ga = tape.slot(a), gb = tape.slot(b);
    k::add_backward(tape.stream(), dy, ga.ptr(), gb.ptr());
    tape.commit(ga);
    tape.commit(gb);
  });
}

Var sub(Tape& t, const Var& a, const Var& b) {
  Tensor y = empty_like(a.value());
  k::sub(t.stream(), a.value(), b.value(), y);
  return finish(t, y, {&a, &b}, [a, b](Tape& tape, const Tensor& dy) {
    GradSlot ga = tape.slot(a), gb = tape.slot(b);
    k::sub_backward(tape.stream(), dy, ga.ptr(), gb.ptr());
    tape.commit(ga);
    tape.commit(gb);
  });
}

Var mul(Tape& t, const Var& a, const Var& b) {
  Tensor y = empty_like(a.value());
  k::mul(t.stream(), a.value(), b.value(), y);
  return finish(t, y, {&a, &b}, [a, b](Tape& tape, const Tensor& dy) {
    GradSlot ga = tape.slot(a), gb = tape.slot(b);
    k::mul_backward(tape.stream(), a.value(), b.value(), dy, ga.ptr(), gb.ptr());
    tape.commit(ga);
    tape.commit(gb);
  });
}

Var scale_shift(Tape& t, const Var& x, float scale, float shift) {
  Tensor y = empty_like(x.value());
  k::scale_shift(t.stream(), x.value(), scale, shift, y);
  return finish(t, y, {&x}, [x, scale](Tape& tape, const Tensor& dy) {
    GradSlot gx = tape.slot(x);
    k::scale_shift_backward(tape.stream(), dy, scale, gx.target);
    tape.commit(gx);
  });
}

Var exp(Tape& t, const Var& x) {
  Tensor y = empty_like(x.value());
  k::exponential(t.stream(), x.value(), y);
  return finish(t, y, {&x}, [x, y](Tape& tape, const Tensor& dy) {
    GradSlot gx = tape.slot(x);
    k::exponential_backward(tape.stream(), y, dy, gx.target);
    tape.commit(gx);
  });
}

Var log(Tape& t, const Var& x) {
  Tensor y = empty_like(x.value());
  k::logarithm(t.stream(), x.value(), y);
  return finish(t, y, {&x}, [x](Tape& tape, const Tensor& dy) {
    GradSlot gx = tape.slot(x);
    k::logarithm_backward(tape.stream(), x.value(), dy, gx.target);
    tape.commit(gx);
  });
}

// ---- per-channel ------------------------------------------------------------------

Var add_channel(Tape& t, const Var& x, const Var& v) {
  Tensor y = empty_like(x.value());
  k::add_channel(t.stream(), x.value(), v.value(), y);
  return finish(t, y, {&x, &v}, [x, v](Tape& tape, const Tensor& dy) {
    GradSlot gx = tape.slot(x), gv = tape.slot(v);
    if (gx) k::copy(tape.stream(), dy, gx.target);
    if (gv) k::add_channel_backward(tape.stream(), dy, gv.target);
    tape.commit(gx);
    tape.commit(gv);
  });
}

Var mul_channel(Tape& t, const Var& x, const Var& v) {
  Tensor y = empty_like(x.value());
  k::mul_channel(t.stream(), x.value(), v.value(), y);
  return finish(t, y, {&x, &v}, [x, v](Tape& tape, const Tensor& dy) {
    GradSlot gx = tape.slot(x), gv = tape.slot(v);
    k::mul_channel_backward(tape.stream(), x.value(), v.value(), dy, gx.ptr(), gv.ptr());
    tape.commit(gx);
    tape.commit(gv);
  });
}

Var mul_sample_channel(Tape& t, const Var& x, const Var& s) {
  const Shape& xs = x.shape();
  const Shape& ss = s.shape();
  const bool ok = xs.rank() == 4 && (ss == Shape{xs[0], xs[1], 1, 1} || ss == Shape{xs[0], xs[1]});
  if (!ok) {
    throw InvalidArgument("nets::mul_sample_channel",
                          "x " + xs.str() + " and scale " + ss.str() + " do not match",
                          "pass x [N, C, H, W] and one scale per sample and channel [N, C, 1, 1]");
  }
  // Per (n, c) is per channel of x seen as one sample of N·C channels.
  const Var flat_x = reshape(t, x, Shape{1, xs[0] * xs[1], xs[2], xs[3]});
  const Var flat_s = reshape(t, s, Shape{xs[0] * xs[1]});
  return reshape(t, mul_channel(t, flat_x, flat_s), xs);
}

Var sum_channels(Tape& t, const Var& x) {
  // [C] for a vector, else the channels of [N, C, ...] (kernels::sum_channels checks).
  const Shape& s = x.shape();
  Tensor y = empty(x, Shape{s.rank() == 1 ? s[0] : s[1]});
  k::sum_channels(t.stream(), x.value(), y);
  return finish(t, y, {&x}, [x](Tape& tape, const Tensor& dy) {
    GradSlot gx = tape.slot(x);
    Tensor zeros = empty_like(x.value());
    tape.stream().fill(zeros, 0.f);
    k::add_channel(tape.stream(), zeros, dy, gx.target);
    tape.commit(gx);
  });
}

Var channel_affine(Tape& t, const Var& x, const Var& scale, const Var& bias) {
  Tensor y = empty_like(x.value());
  k::channel_affine(t.stream(), x.value(), scale.value(), bias.value(), y);
  return finish(t, y, {&x, &scale, &bias}, [x, scale, bias](Tape& tape, const Tensor& dy) {
    GradSlot gx = tape.slot(x), gs = tape.slot(scale), gb = tape.slot(bias);
    k::channel_affine_backward(tape.stream(), x.value(), scale.value(), dy, gx.ptr(), gs.ptr(),
                               gb.ptr());
    tape.commit(gx);
    tape.commit(gs);
    tape.commit(gb);
  });
}

// ---- normalization and gating -------------------------------------------------------

Var layer_norm_channels(Tape& t, const Var& x, const Var& gamma, const Var& beta, float eps) {
  Tensor y = empty_like(x.value());
  k::layer_norm_channels(t.stream(), x.value(), gamma.value(), beta.value(), eps, y);
  return finish(t, y, {&x, &gamma, &beta}, [x, gamma, beta, eps](Tape& tape, const Tensor& dy) {
    GradSlot gx = tape.slot(x), gg = tape.slot(gamma), gb = tape.slot(beta);
    k::layer_norm_channels_backward(tape.stream(), x.value(), gamma.value(), dy, eps, gx.ptr(),
                                    gg.ptr(), gb.ptr());
    tape.commit(gx);
    tape.commit(gg);
    tape.commit(gb);
  });
}

Var simple_gate(Tape& t, const Var& x) {
  const Shape& s = x.shape();
  std::vector<std::int64_t> dims(s.dims().begin(), s.dims().end());
  if (s.rank() >= 2) dims[1] /= 2;
  Tensor y = empty(x, Shape(dims));
  k::simple_gate(t.stream(), x.value(), y);
  return finish(t, y, {&x}, [x](Tape& tape, const Tensor& dy) {
    GradSlot gx = tape.slot(x);
    k::simple_gate_backward(tape.stream(), x.value(), dy, gx.target);
    tape.commit(gx);
  });
}

// ---- activations ------------------------------------------------------------------

Var relu(Tape& t, const Var& x) {
  Tensor y = empty_like(x.value());
  k::relu(t.stream(), x.value(), y);
  return finish(t, y, {&x}, [x](Tape& tape, const Tensor& dy) {
    GradSlot gx = tape.slot(x);
    k::relu_backward(tape.stream(), x.value(), dy, gx.target);
    tape.commit(gx);
  });
}

Var leaky_relu(Tape& t, const Var& x, float slope) {
  Tensor y = empty_like(x.value());
  k::leaky_relu(t.stream(), x.value(), slope, y);
  return finish(t, y, {&x}, [x, slope](Tape& tape, const Tensor& dy) {
    GradSlot gx = tape.slot(x);
    k::leaky_relu_backward(tape.stream(), x.value(), slope, dy, gx.target);
    tape.commit(gx);
  });
}

Var prelu(Tape& t, const Var& x, const Var& slope) {
  Tensor y = empty_like(x.value());
  k::prelu(t.stream(), x.value(), slope.value(), y);
  return finish(t, y, {&x, &slope}, [x, slope](Tape& tape, const Tensor& dy) {
    GradSlot gx = tape.slot(x), gs = tape.slot(slope);
    k::prelu_backward(tape.stream(), x.value(), slope.value(), dy, gx.ptr(), gs.ptr());
    tape.commit(gx);
    tape.commit(gs);
  });
}

Var sigmoid(Tape& t, const Var& x) {
  Tensor y = empty_like(x.value());
  k::sigmoid(t.stream(), x.value(), y);
  return finish(t, y, {&x}, [x, y](Tape& tape, const Tensor& dy) {
    GradSlot gx = tape.slot(x);
    k::sigmoid_backward(tape.stream(), y, dy, gx.target);
    tape.commit(gx);
  });
}

Var tanh(Tape& t, const Var& x) {
  Tensor y = empty_like(x.value());
  k::tanh_activation(t.stream(), x.value(), y);
  return finish(t, y, {&x}, [x, y](Tape& tape, const Tensor& dy) {
    GradSlot gx = tape.slot(x);
    k::tanh_activation_backward(tape.stream(), y, dy, gx.target);
    tape.commit(gx);
  });
}

Var softmax(Tape& t, const Var& x) {
  Tensor y = empty_like(x.value());
  k::softmax(t.stream(), x.value(), y);
  return finish(t, y, {&x}, [x, y](Tape& tape, const Tensor& dy) {
    GradSlot gx = tape.slot(x);
    k::softmax_backward(tape.stream(), y, dy, gx.target);
    tape.commit(gx);
  });
}

Var log_softmax(Tape& t, const Var& x) {
  Tensor y = empty_like(x.value());
  k::log_softmax(t.stream(), x.value(), y);
  return finish(t, y, {&x}, [x, y](Tape& tape, const Tensor& dy) {
    GradSlot gx = tape.slot(x);
    k::log_softmax_backward(tape.stream(), y, dy, gx.target);
    tape.commit(gx);
  });
}

// ---- layers' compute --------------------------------------------------------------

struct ConvPlans::Entry {
  Shape x, weight;
  k::Conv2dParams p;
  k::Conv2dPlan plan;
  std::weak_ptr<const detail::VarState> source;  // the weight plan.pack() read
  std::uint64_t version = 0;
};

ConvPlans::ConvPlans() : mutex_(std::make_unique<std::mutex>()) {}
ConvPlans::~ConvPlans() = default;

k::Conv2dPlan& ConvPlans::entry(const Device& device, const Shape& x, const Shape& weight,
                                const k::Conv2dParams& p, Entry** found) const {
  for (Entry& e : entries_) {
    if (e.plan.made_for(device) && e.x == x && e.weight == weight && e.p == p) {
      *found = &e;
      return e.plan;
    }
  }
  Entry e;
  e.x = x;
  e.weight = weight;
  e.p = p;
  e.plan = k::Conv2dPlan(device, x, weight, p);
  entries_.push_back(std::move(e));
  *found = &entries_.back();
  return entries_.back().plan;
}

k::Conv2dPlan ConvPlans::get(Stream& stream, const Shape& x, const Var& weight,
                             const k::Conv2dParams& p) const {
  const std::shared_ptr<const detail::VarState> current = weight.state();
  if (!current) {
    throw InvalidArgument("ConvPlans::get", "the weight is undefined", "pass a conv weight");
  }
  const std::lock_guard<std::mutex> lock(*mutex_);
  Entry* e = nullptr;
  k::Conv2dPlan& plan = entry(stream.device(), x, weight.shape(), p, &e);
  if (plan.reads_packed_weight() &&
      (!plan.packed() || e->source.lock() != current || e->version != weight.version())) {
    plan.pack(stream, weight.value());
    e->source = current;
    e->version = weight.version();
  }
  return plan;
}

k::PlaneLayout ConvPlans::input_layout(const Tape& t, const Shape& x, const Var& weight,
                                       const Var& bias, const k::Conv2dParams& p) const {
  if (t.needs_grad({&weight, &bias})) return {};
  const std::lock_guard<std::mutex> lock(*mutex_);
  Entry* e = nullptr;
  return entry(t.device(), x, weight.shape(), p, &e).input_layout();
}

Tensor plain(Tape& t, const Var& x) {
  return x.padded() ? k::unpad(t.stream(), x.planes()) : x.value();
}

Var conv2d(Tape& t, const Var& x, const Var& weight, const Var& bias,
           const kernels::Conv2dParams& p, const ConvPlans* plans, const Var& residual,
           const k::PlaneLayout& out) {
  const bool grad = t.needs_grad({&x, &weight, &bias, &residual});
  if (grad && p.relu_input) {  // the backward kernels differentiate conv(x)
    k::Conv2dParams q = p;
    q.relu_input = false;
    return conv2d(t, relu(t, x.padded() ? Var(plain(t, x)) : x), weight, bias, q, plans, residual,
                  out);
  }
  Stream& stream = t.stream();
  const k::Conv2dPlan plan = plans != nullptr
                                 ? plans->get(stream, x.shape(), weight, p)
                                 : k::Conv2dPlan(t.device(), x.shape(), weight.shape(), p);
  // x and the residual as the plan reads them: padded in the layouts it
  // takes, else plain.
  k::Planes xp = x.planes();
  if (xp.padded() && !(xp.layout == plan.input_layout())) xp = k::Planes::of(k::unpad(stream, xp));
  k::Planes rp;
  if (residual.defined()) {
    rp = residual.planes();
    if (rp.padded() && !plan.residual_misfit(rp).empty()) rp = k::Planes::of(k::unpad(stream, rp));
  }
  const bool padded_out = !grad && !out.plain() && plan.writes_padded();
  const k::Planes yp = padded_out ? k::Planes::make(stream, plan.output_shape(), out)
                                  : k::Planes::of(Tensor::empty(t.device(), plan.output_shape()));
  plan.run(stream, xp, weight.value(), bias.defined() ? &bias.value() : nullptr, yp,
           residual.defined() ? &rp : nullptr);
  if (padded_out) return Var(yp);
  const Tensor& y = yp.data;
  // The backward reads x plain (a padded x needs no gradient itself, but the
  // weight's may need it).
  const Tensor x_value = grad && t.needs_grad({&weight}) ? plain(t, x) : Tensor();
  auto step = [x, x_value, weight, bias, residual, y, p](Tape& tape, const Tensor& dy) {
    Stream& s = tape.stream();
    // The backward kernels take the pre-activation gradient; ReLU/LeakyReLU
    // derivatives follow sign(y) = sign(pre-activation).
    Tensor d_pre = dy;
    if (p.activation == k::Activation::relu) {
      d_pre = empty_like(dy);
      k::relu_backward(s, y, dy, d_pre);
    } else if (p.activation == k::Activation::leaky_relu) {
      d_pre = empty_like(dy);
      k::leaky_relu_backward(s, y, p.leaky_slope, dy, d_pre);
    }
    k::Conv2dParams pb = p;
    pb.activation = k::Activation::none;
    pb.algo = k::Conv2dAlgo::auto_select;
    GradSlot gx = tape.slot(x), gw = tape.slot(weight), gb = tape.slot(bias);
    GradSlot gr = tape.slot(residual);
    // The residual's gradient: d_pre over its channels [0, Cr).
    if (gr) k::slice(s, d_pre, k::SliceStart{}, gr.target);
    if (gx) k::conv2d_backward_data(s, d_pre, weight.value(), gx.target, pb);
    if (gw) {
      k::conv2d_backward_weight(s, x_value, d_pre, gw.target, gb.ptr(), pb);
    } else if (gb) {
      k::sum_channels(s, d_pre, gb.target);
    }
    tape.commit(gx);
    tape.commit(gw);
    tape.commit(gb);
    tape.commit(gr);
  };
  return finish(t, y, {&x, &weight, &bias, &residual}, step);
}

Var linear(Tape& t, const Var& x, const Var& weight, const Var& bias) {
  Tensor y = empty(x, Shape{x.shape()[0], weight.shape()[1]});
  const Tensor* b = bias.defined() ? &bias.value() : nullptr;
  k::matmul(t.stream(), x.value(), weight.value(), y, b);
  return finish(t, y, {&x, &weight, &bias}, [x, weight, bias](Tape& tape, const Tensor& dy) {
    GradSlot gx = tape.slot(x), gw = tape.slot(weight), gb = tape.slot(bias);
    k::matmul_backward(tape.stream(), x.value(), weight.value(), dy, gx.ptr(), gw.ptr(), gb.ptr());
    tape.commit(gx);
    tape.commit(gw);
    tape.commit(gb);
  });
}

Var max_pool2d(Tape& t, const Var& x, const kernels::Pool2d& p, const k::PlaneLayout& out) {
  const Shape shape = k::pool_output_shape(x.shape(), p);
  if (!out.plain() && !t.needs_grad({&x})) {
    const k::Planes y = k::Planes::make(t.stream(), shape, out);
    k::max_pool2d_into_padded(t.stream(), plain(t, x), p, y);
    return Var(y);
  }
  Tensor y = empty(x, shape);
  // The argmax indices only when the backward can run.
  Tensor indices;
  if (t.needs_grad({&x})) indices = Tensor::empty(x.value().device(), shape, DType::i32);
  k::max_pool2d(t.stream(), x.value(), p, y, indices);
  return finish(t, y, {&x}, [x, p, indices](Tape& tape, const Tensor& dy) {
    GradSlot gx = tape.slot(x);
    k::max_pool2d_backward(tape.stream(), dy, indices, p, gx.target);
    tape.commit(gx);
  });
}

Var avg_pool2d(Tape& t, const Var& x, const kernels::Pool2d& p, bool count_include_pad) {
  Tensor y = empty(x, k::pool_output_shape(x.shape(), p));
  k::avg_pool2d(t.stream(), x.value(), p, count_include_pad, y);
  return finish(t, y, {&x}, [x, p, count_include_pad](Tape& tape, const Tensor& dy) {
    GradSlot gx = tape.slot(x);
    k::avg_pool2d_backward(tape.stream(), dy, p, count_include_pad, gx.target);
    tape.commit(gx);
  });
}

Var global_avg_pool(Tape& t, const Var& x) {
  Tensor y = empty(x, Shape{x.shape()[0], x.shape()[1], 1, 1});
  k::global_avg_pool(t.stream(), x.value(), y);
  return finish(t, y, {&x}, [x](Tape& tape, const Tensor& dy) {
    GradSlot gx = tape.slot(x);
    k::global_avg_pool_backward(tape.stream(), dy, gx.target);
    tape.commit(gx);
  });
}

Var resize(Tape& t, const Var& x, kernels::ResizeMode mode, std::int64_t out_h,
           std::int64_t out_w) {
  if (x.shape().rank() != 4) {
    throw InvalidArgument("nets::resize", "x has shape " + x.shape().str() + ", not NCHW",
                          "pass a 4-D tensor");
  }
  Tensor y = empty(x, Shape{x.shape()[0], x.shape()[1], out_h, out_w});
  k::resize(t.stream(), x.value(), mode, y);
  return finish(t, y, {&x}, [x, mode](Tape& tape, const Tensor& dy) {
    GradSlot gx = tape.slot(x);
    k::resize_backward(tape.stream(), dy, mode, gx.target);
    tape.commit(gx);
  });
}

Var pad(Tape& t, const Var& x, const kernels::Pad2d& p, float value) {
  const Shape& s = x.shape();
  if (s.rank() != 4) {
    throw InvalidArgument("nets::pad", "x has shape " + s.str() + ", not NCHW",
                          "pass a 4-D tensor");
  }
  Tensor y = empty(x, Shape{s[0], s[1], s[2] + p.top + p.bottom, s[3] + p.left + p.right});
  k::pad(t.stream(), x.value(), p, value, y);
  return finish(t, y, {&x}, [x, p](Tape& tape, const Tensor& dy) {
    GradSlot gx = tape.slot(x);
    k::pad_backward(tape.stream(), dy, p, gx.target);
    tape.commit(gx);
  });
}

Var concat_channels(Tape& t, std::span<const Var> xs) {
  if (xs.empty()) throw InvalidArgument("nets::concat_channels", "no inputs", "pass at least one");
  std::vector<Tensor> values;
  std::int64_t channels = 0;
  bool grad = false;
  for (const Var& v : xs) {
    values.push_back(v.value());
    if (v.shape().rank() != 4) {
      throw InvalidArgument("nets::concat_channels", "input shape " + v.shape().str(),
                            "pass NCHW tensors");
    }
    channels += v.shape()[1];
    grad = grad || t.needs_grad({&v});
  }
  const Shape& s0 = xs[0].shape();
  Tensor y = empty(xs[0], Shape{s0[0], channels, s0[2], s0[3]});
  k::concat_channels(t.stream(), values, y);
  Var out = t.output(y, grad);
  if (grad) {
    std::vector<Var> inputs(xs.begin(), xs.end());
    t.record([out, inputs](Tape& tape) {
      const Tensor& dy = Tape::grad_of(out);
      if (!dy.defined()) return;
      std::vector<GradSlot> slots;
      std::vector<Tensor> targets;
      for (const Var& v : inputs) {
        slots.push_back(tape.slot(v));
        // Inputs needing no gradient still take their part of dy (a scratch tensor).
        targets.push_back(slots.back() ? slots.back().target : empty_like(v.value()));
      }
      k::concat_channels_backward(tape.stream(), dy, targets);
      for (const GradSlot& g : slots) tape.commit(g);
    });
  }
  return out;
}

Var slice(Tape& t, const Var& x, const kernels::SliceStart& start, const Shape& shape) {
  Tensor y = empty(x, shape);
  k::slice(t.stream(), x.value(), start, y);
  return finish(t, y, {&x}, [x, start](Tape& tape, const Tensor& dy) {
    GradSlot gx = tape.slot(x);
    k::slice_backward(tape.stream(), dy, start, gx.target);
    tape.commit(gx);
  });
}

Var pixel_shuffle(Tape& t, const Var& x, int r) {
  const Shape& s = x.shape();
  if (s.rank() != 4 || r < 1 || s[1] % (std::int64_t(r) * r) != 0) {
    throw InvalidArgument("nets::pixel_shuffle",
                          "x " + s.str() + " with factor " + std::to_string(r),
                          "pass NCHW x whose channels are a multiple of r², r >= 1");
  }
  Tensor y = empty(x, Shape{s[0], s[1] / (r * r), s[2] * r, s[3] * r});
  k::pixel_shuffle(t.stream(), x.value(), r, y);
  return finish(t, y, {&x}, [x, r](Tape& tape, const Tensor& dy) {
    GradSlot gx = tape.slot(x);
    k::pixel_unshuffle(tape.stream(), dy, r, gx.target);
    tape.commit(gx);
  });
}

Var pixel_unshuffle(Tape& t, const Var& x, int r) {
  const Shape& s = x.shape();
  if (s.rank() != 4 || r < 1 || s[2] % r != 0 || s[3] % r != 0) {
    throw InvalidArgument("nets::pixel_unshuffle",
                          "x " + s.str() + " with factor " + std::to_string(r),
                          "pass NCHW x whose height and width are multiples of r, r >= 1");
  }
  Tensor y = empty(x, Shape{s[0], s[1] * r * r, s[2] / r, s[3] / r});
  k::pixel_unshuffle(t.stream(), x.value(), r, y);
  return finish(t, y, {&x}, [x, r](Tape& tape, const Tensor& dy) {
    GradSlot gx = tape.slot(x);
    k::pixel_shuffle(tape.stream(), dy, r, gx.target);
    tape.commit(gx);
  });
}

Var reshape(Tape& t, const Var& x, const Shape& shape) {
  Tensor y = x.value().reshape(shape);
  return finish(t, y, {&x}, [x](Tape& tape, const Tensor& dy) {
    GradSlot gx = tape.slot(x);
    k::copy(tape.stream(), dy.reshape(x.shape()), gx.target);
    tape.commit(gx);
  });
}

// ---- geometry ---------------------------------------------------------------------

Var grid_sample(Tape& t, const Var& input, const Var& grid, kernels::GridSampleOptions o) {
  const Shape& s = input.shape();
  const Shape& g = grid.shape();
  if (s.rank() != 4 || g.rank() != 4) {
    throw InvalidArgument("nets::grid_sample",
                          "input " + s.str() + " and grid " + g.str() + " must be 4-D",
                          "pass NCHW input and N×H×W×2 grid");
  }
  Tensor y = empty(input, Shape{s[0], s[1], g[1], g[2]});
  k::grid_sample(t.stream(), input.value(), grid.value(), y, o);
  return finish(t, y, {&input, &grid}, [input, grid, o](Tape& tape, const Tensor& dy) {
    GradSlot gi = tape.slot(input), gg = tape.slot(grid);
    k::grid_sample_backward(tape.stream(), input.value(), grid.value(), dy, gi.ptr(), gg.ptr(), o);
    tape.commit(gi);
    tape.commit(gg);
  });
}

Var affine_grid(Tape& t, const Var& theta, std::int64_t height, std::int64_t width,
                bool align_corners) {
  Tensor grid = empty(theta, Shape{theta.shape()[0], height, width, 2});
  k::affine_grid(t.stream(), theta.value(), grid, align_corners);
  return finish(t, grid, {&theta}, [theta, align_corners](Tape& tape, const Tensor& dy) {
    GradSlot gt = tape.slot(theta);
    k::affine_grid_backward(tape.stream(), dy, gt.target, align_corners);
    tape.commit(gt);
  });
}

// ---- reductions -------------------------------------------------------------------

Var sum_all(Tape& t, const Var& x) {
  Tensor y = empty(x, Shape{1});
  k::sum_all(t.stream(), x.value(), y);
  return finish(t, y, {&x}, [x](Tape& tape, const Tensor& dy) {
    GradSlot gx = tape.slot(x);
    k::sum_all_backward(tape.stream(), dy, gx.target);
    tape.commit(gx);
  });
}

Var mean_all(Tape& t, const Var& x) {
  Tensor y = empty(x, Shape{1});
  k::mean_all(t.stream(), x.value(), y);
  return finish(t, y, {&x}, [x](Tape& tape, const Tensor& dy) {
    GradSlot gx = tape.slot(x);
    k::mean_all_backward(tape.stream(), dy, gx.target);
    tape.commit(gx);
  });
}

Var sum_rows(Tape& t, const Var& x) {
  Tensor y = empty(x, Shape{rows_of(x)});
  k::sum_rows(t.stream(), x.value(), y);
  return finish(t, y, {&x}, [x](Tape& tape, const Tensor& dy) {
    GradSlot gx = tape.slot(x);
    k::sum_rows_backward(tape.stream(), dy, gx.target);
    tape.commit(gx);
  });
}

Var mean_rows(Tape& t, const Var& x) {
  Tensor y = empty(x, Shape{rows_of(x)});
  k::mean_rows(t.stream(), x.value(), y);
  return finish(t, y, {&x}, [x](Tape& tape, const Tensor& dy) {
    GradSlot gx = tape.slot(x);
    k::mean_rows_backward(tape.stream(), dy, gx.target);
    tape.commit(gx);
  });
}

Var l2norm_rows(Tape& t, const Var& x) {
  Tensor y = empty(x, Shape{rows_of(x)});
  k::l2norm_rows(t.stream(), x.value(), y);
  return finish(t, y, {&x}, [x, y](Tape& tape, const Tensor& dy) {
    GradSlot gx = tape.slot(x);
    k::l2norm_rows_backward(tape.stream(), x.value(), y, dy, gx.target);
    tape.commit(gx);
  });
}

// ---- losses -----------------------------------------------------------------------

namespace {

// L1 / MSE / Charbonnier share one shape: d pred from the kernel, d target = −d pred.
template <class Fwd, class Bwd>
Var pointwise_loss(Tape& t, const Var& pred, const Var& target, Fwd fwd, Bwd bwd) {
  Tensor y = empty(pred, Shape{1});
  fwd(t.stream(), pred.value(), target.value(), y);
  return finish(t, y, {&pred, &target}, [pred, target, bwd](Tape& tape, const Tensor& g) {
    GradSlot gp = tape.slot(pred);
    Tensor d = gp ? gp.target : empty_like(pred.value());
    bwd(tape.stream(), pred.value(), target.value(), g, d);
    if (target.requires_grad()) commit_negated(tape, target, d);
    tape.commit(gp);
  });
}

}  // namespace

Var l1_loss(Tape& t, const Var& pred, const Var& target) {
  return pointwise_loss(t, pred, target, k::l1_loss, k::l1_loss_backward);
}

Var mse_loss(Tape& t, const Var& pred, const Var& target) {
  return pointwise_loss(t, pred, target, k::mse_loss, k::mse_loss_backward);
}

Var charbonnier_loss(Tape& t, const Var& pred, const Var& target, float eps) {
  return pointwise_loss(
      t, pred, target,
      [eps](Stream& s, const Tensor& p, const Tensor& q, const Tensor& y) {
        k::charbonnier_loss(s, p, q, eps, y);
      },
      [eps](Stream& s, const Tensor& p, const Tensor& q, const Tensor& g, const Tensor& d) {
        k::charbonnier_loss_backward(s, p, q, eps, g, d);
      });
}

Var cosine_similarity(Tape& t, const Var& a, const Var& b) {
  Tensor y = empty(a, Shape{rows_of(a)});
  k::cosine_similarity(t.stream(), a.value(), b.value(), y);
  return finish(t, y, {&a, &b}, [a, b](Tape& tape, const Tensor& dy) {
    GradSlot ga = tape.slot(a), gb = tape.slot(b);
    const Tensor da = ga ? ga.target : empty_like(a.value());
    const Tensor db = gb ? gb.target : empty_like(b.value());
    k::cosine_similarity_backward(tape.stream(), a.value(), b.value(), dy, da, db);
    tape.commit(ga);
    tape.commit(gb);
  });
}

Var cross_entropy(Tape& t, const Var& logits, const Tensor& labels) {
  Tensor y = empty(logits, Shape{1});
  k::cross_entropy(t.stream(), logits.value(), labels, y);
  return finish(t, y, {&logits}, [logits, labels](Tape& tape, const Tensor& g) {
    GradSlot gl = tape.slot(logits);
    k::cross_entropy_backward(tape.stream(), logits.value(), labels, g, gl.target);
    tape.commit(gl);
  });
}

}  // namespace vkjr2::nets
