#include <vkjr2/kernels/basic.hpp>
#include <vkjr2/nets/autograd.hpp>
#include <vkjr2/runtime/error.hpp>

#include <utility>

#include "internal/var_state.hpp"

namespace vkjr2::nets {

Var::Var(Tensor value, bool requires_grad) : state_(std::make_shared<detail::VarState>()) {
  if (!value.defined()) throw InvalidArgument("Var", "the tensor is undefined", "pass a tensor");
  state_->value = std::move(value);
  state_->requires_grad = requires_grad;
}

Var::Var(const kernels::Planes& planes) : state_(std::make_shared<detail::VarState>()) {
  if (!planes.defined()) throw InvalidArgument("Var", "the planes are undefined", "pass planes");
  state_->value = planes.data;
  if (planes.padded()) {
    state_->padded_shape = planes.shape;
    state_->layout = planes.layout;
  }
}

bool Var::padded() const noexcept { return state_ && !state_->layout.plain(); }

kernels::Planes Var::planes() const {
  if (!state_) throw InvalidArgument("Var", "the Var is undefined", "assign it from an op first");
  if (state_->layout.plain()) return kernels::Planes::of(state_->value);
  return kernels::Planes{state_->value, state_->padded_shape, state_->layout};
}

const Shape& Var::shape() const {
  if (!state_) throw InvalidArgument("Var", "the Var is undefined", "assign it from an op first");
  return state_->layout.plain() ? state_->value.shape() : state_->padded_shape;
}

bool Var::requires_grad() const noexcept { return state_ && state_->requires_grad; }
bool Var::has_grad() const noexcept { return state_ && state_->grad.defined(); }
std::uint64_t Var::version() const noexcept { return state_ ? state_->version : 0; }
void Var::mark_modified() const noexcept {
  if (state_) ++state_->version;
}

const Tensor& Var::value() const {
  if (!state_) throw InvalidArgument("Var", "the Var is undefined", "assign it from an op first");
  if (!state_->layout.plain()) {
    throw InvalidArgument("Var",
                          "the Var holds padded planes " + state_->layout.str() + " of " +
                              state_->padded_shape.str() + ", not a plain tensor",
                          "read it with planes(), or have its producer write it plain");
  }
  return state_->value;
}

const Tensor& Var::grad() const {
  static const Tensor kNone;
  return state_ ? state_->grad : kNone;
}

void Var::zero_grad() const {
  if (state_) state_->grad = Tensor();
}

void Var::set_value(Tensor value) const {
  if (!state_)
    throw InvalidArgument("Var::set_value", "the Var is undefined", "construct it first");
  if (padded()) {
    throw InvalidArgument("Var::set_value", "the Var holds padded planes",
                          "set the value of plain Vars (parameters) only");
  }
  if (!(value.shape() == state_->value.shape())) {
    throw InvalidArgument("Var::set_value",
                          "new value has shape " + value.shape().str() + ", the Var has " +
                              state_->value.shape().str(),
                          "pass a tensor of the same shape");
  }
  state_->value = std::move(value);
  state_->grad = Tensor();
  ++state_->version;
}

void Var::set_requires_grad(bool on) const {
  if (on && padded()) {
    throw InvalidArgument("Var::set_requires_grad", "a padded Var takes no gradient",
                          "have its producer write it plain");
  }
  if (state_) state_->requires_grad = on;
}

Tape::Tape(Stream& stream, bool recording) : stream_(&stream), recording_(recording) {}

const Device& Tape::device() const { return stream_->device(); }

bool Tape::needs_grad(std::initializer_list<const Var*> inputs) const noexcept {
  if (!recording_) return false;
  for (const Var* v : inputs) {
    if (v != nullptr && v->requires_grad()) return true;
  }
  return false;
}

Var Tape::output(Tensor value, bool requires_grad) const {
  return Var(std::move(value), requires_grad && recording_);
}

void Tape::record(std::function<void(Tape&)> step) {
  if (recording_) steps_.push_back(std::move(step));
}

void Tape::backward(const Var& loss) {
  if (!loss.requires_grad()) {
    throw InvalidArgument("Tape::backward",
                          "the loss does not depend on any Var needing a gradient",
                          "create parameters/inputs with requires_grad = true and keep the tape "
                          "recording during the forward pass");
  }
  if (loss.numel() != 1) {
    throw InvalidArgument("Tape::backward",
                          "the loss has shape " + loss.shape().str() + ", not one element",
                          "reduce it first (mean_all / sum_all)");
  }
  GradSlot seed = slot(loss);
  stream_->fill(seed.target, 1.f);
  commit(seed);
  auto steps = std::move(steps_);
  steps_.clear();
  for (auto it = steps.rbegin(); it != steps.rend(); ++it) (*it)(*this);
}

const Tensor& Tape::grad_of(const Var& output) { return output.grad(); }

GradSlot Tape::slot(const Var& input) const {
  GradSlot s;
  if (!input.requires_grad()) return s;
  s.var = input;
  const Tensor& v = input.value();
  s.target = Tensor::empty(v.device(), v.shape(), v.dtype());
  return s;
}

void Tape::commit(const GradSlot& slot) {
  if (!slot.target.defined()) return;
  auto& state = *slot.var.state();
  if (state.grad.defined()) {
    kernels::axpy(*stream_, 1.f, slot.target, state.grad);
    stream_->keep_alive(slot.target);
  } else {
    state.grad = slot.target;
  }
}

std::vector<std::pair<std::string, Var>> Module::named_parameters() const {
  std::vector<std::pair<std::string, Var>> out;
  collect("", false, out);
  return out;
}

std::vector<Var> Module::parameters() const {
  std::vector<Var> out;
  for (auto& [name, v] : named_parameters()) out.push_back(v);
  return out;
}

std::vector<std::pair<std::string, Var>> Module::named_buffers() const {
  std::vector<std::pair<std::string, Var>> out;
  collect("", true, out);
  return out;
}

void Module::zero_grad() const {
  for (auto& [name, v] : named_parameters()) v.zero_grad();
}

void Module::train(bool on) {
  training_ = on;
  for (auto& [name, child] : children_) child->train(on);
}

Var Module::register_parameter(std::string name, Tensor value) {
  params_.emplace_back(std::move(name), Var(std::move(value), true));
  return params_.back().second;
}

Var Module::register_buffer(std::string name, Tensor value) {
  buffers_.emplace_back(std::move(name), Var(std::move(value), false));
  return buffers_.back().second;
}

void Module::collect(const std::string& prefix, bool buffers,
                     std::vector<std::pair<std::string, Var>>& out) const {
  for (const auto& [name, v] : buffers ? buffers_ : params_) out.emplace_back(prefix + name, v);
  for (const auto& [name, child] : children_) child->collect(prefix + name + ".", buffers, out);
}

}  // namespace vkjr2::nets
