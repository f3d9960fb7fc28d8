// Reverse-mode automatic differentiation over the device kernels.
//
// A Var is a device tensor with an optional gradient. Ops (nets/ops.hpp) run
// their forward kernel on the Tape's Stream at once and, when the tape is
// recording and an input needs a gradient, record a closure that runs the
// matching backward kernels. Tape::backward() replays the closures in reverse
// order on the same Stream: no host round-trips inside a step. Gradients
// accumulate (a Var used twice receives the sum) until zero_grad().
//
// Ownership: a closure keeps the tensors its backward needs alive; clear()
// (or the next backward()) drops them. Parameters keep their gradient across
// tape clears; intermediate Vars are freed with the tape.
#pragma once

#include <vkjr2/kernels/planes.hpp>
#include <vkjr2/runtime/stream.hpp>

#include <cstdint>
#include <functional>
#include <memory>
#include <string>
#include <vector>

namespace vkjr2::nets {

namespace detail {
struct VarState;  // nets/internal/var_state.hpp
}  // namespace detail

class Var {
 public:
  Var() = default;
  // Wraps a tensor; requires_grad marks a leaf whose gradient is wanted
  // (a parameter, or an input image for pixel gradients).
  explicit Var(Tensor value, bool requires_grad = false);
  // Wraps an activation as the kernels store it (kernels/planes.hpp): plain
  // planes are the tensor; padded ones (an inference activation written
  // straight into the zero-bordered input of the convolution that reads it)
  // are read through planes() only, and never need a gradient.
  explicit Var(const kernels::Planes& planes);

  bool defined() const noexcept { return state_ != nullptr; }
  // The tensor; InvalidArgument for a padded Var (see planes()).
  const Tensor& value() const;
  // The value as planes: plain (value()) or padded.
  kernels::Planes planes() const;
  bool padded() const noexcept;
  const Shape& shape() const;
  std::int64_t numel() const { return shape().numel(); }
  bool requires_grad() const noexcept;
  // The accumulated gradient; undefined when no gradient reached this Var.
  const Tensor& grad() const;
  bool has_grad() const noexcept;
  // Drops the accumulated gradient (the next backward starts from zero).
  void zero_grad() const;
  // Replaces the value in place (same shape): loading weights, optimizer
  // state restore. Gradients are dropped.
  void set_value(Tensor value) const;
  void set_requires_grad(bool on) const;
  // Counts the writes to the value: set_value, optimizer steps and checkpoint
  // loads call mark_modified(); code that writes a parameter's tensor in place
  // by other means must call it too. Caches derived from a Var (packed conv
  // weights, folded layers) compare versions to know when to rebuild.
  std::uint64_t version() const noexcept;
  void mark_modified() const noexcept;

  const std::shared_ptr<detail::VarState>& state() const noexcept { return state_; }

 private:
  std::shared_ptr<detail::VarState> state_;
};

// Where a backward kernel writes one input's gradient: a fresh tensor that
// commit() makes the Var's gradient when it has none yet, or adds onto it
// (fixed order: deterministic). `target` is undefined when the Var needs no
// gradient; ptr() is then null, as the kernels' optional outputs expect.
struct GradSlot {
  Var var;
  Tensor target;
  const Tensor* ptr() const noexcept { return target.defined() ? &target : nullptr; }
  explicit operator bool() const noexcept { return target.defined(); }
};

class Tape {
 public:
  explicit Tape(Stream& stream, bool recording = true);
  Tape(const Tape&) = delete;
  Tape& operator=(const Tape&) = delete;

  Stream& stream() const noexcept { return *stream_; }
  const Device& device() const;

  // Recording off = inference: ops run their forward only and keep nothing.
  bool recording() const noexcept { return recording_; }
  void set_recording(bool on) noexcept { recording_ = on; }
  // True when a backward must be recorded for an op over these inputs.
  bool needs_grad(std::initializer_list<const Var*> inputs) const noexcept;

  // A Var for an op's output (needs a gradient when any input does).
  Var output(Tensor value, bool requires_grad) const;

  // Records a backward step; it runs when backward() reaches it.
  void record(std::function<void(Tape&)> step);
  std::size_t size() const noexcept { return steps_.size(); }

  // Seeds d loss = 1 (loss has one element) and runs the recorded steps in
  // reverse. The steps are then dropped (the tape can record the next step).
  // Nothing is submitted: call stream().run() before reading gradients.
  void backward(const Var& loss);
  // Drops the recorded steps without running them.
  void clear() noexcept { steps_.clear(); }

  // Gradient flowing into an op's output (undefined when none reached it:
  // the op's backward can then be skipped).
  static const Tensor& grad_of(const Var& output);
  GradSlot slot(const Var& input) const;
  void commit(const GradSlot& slot);

 private:
  Stream* stream_;
  bool recording_;
  std::vector<std::function<void(Tape&)>> steps_;
};

// A Module owns named parameters and child modules (PyTorch-style names:
// "block1.conv0.weight"). Layers derive from it; models compose layers.
class Module {
 public:
  Module() = default;
  virtual ~Module() = default;
  Module(const Module&) = delete;
  Module& operator=(const Module&) = delete;

  // Every parameter of this module and its children, in registration order.
  std::vector<std::pair<std::string, Var>> named_parameters() const;
  std::vector<Var> parameters() const;
  // Named non-trainable state (BatchNorm running statistics), same order rule.
  std::vector<std::pair<std::string, Var>> named_buffers() const;
  void zero_grad() const;

  void train(bool on = true);
  void eval() { train(false); }
  bool training() const noexcept { return training_; }

 protected:
  Var register_parameter(std::string name, Tensor value);
  Var register_buffer(std::string name, Tensor value);
  template <class M>
  M& register_module(std::string name, std::unique_ptr<M> module) {
    M& ref = *module;
    children_.emplace_back(std::move(name), std::move(module));
    return ref;
  }

 private:
  void collect(const std::string& prefix, bool buffers,
               std::vector<std::pair<std::string, Var>>& out) const;
  std::vector<std::pair<std::string, Var>> params_;
  std::vector<std::pair<std::string, Var>> buffers_;
  std::vector<std::pair<std::string, std::unique_ptr<Module>>> children_;
  bool training_ = true;
};

}  // namespace vkjr2::nets
