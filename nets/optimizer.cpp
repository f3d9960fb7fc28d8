#include <vkjr2/nets/optimizer.hpp>
#include <vkjr2/runtime/error.hpp>

#include <cmath>
#include <numbers>
#include <utility>

namespace vkjr2::nets {
namespace {

std::vector<Tensor> zeros_like_all(Stream& stream, const NamedVars& params) {
  std::vector<Tensor> out;
  out.reserve(params.size());
  for (const auto& [name, v] : params) {
    out.push_back(Tensor::empty(v.value().device(), v.shape()));
    stream.fill(out.back(), 0.f);
  }
  return out;
}

std::vector<Tensor> zeros_like_all(const NamedVars& params) {
  if (params.empty()) return {};
  Stream stream(params.front().second.value().device());
  auto out = zeros_like_all(stream, params);
  stream.run();
  return out;
}

}  // namespace

Optimizer::Optimizer(NamedVars params) : params_(std::move(params)) {
  if (params_.empty()) {
    throw InvalidArgument("Optimizer", "no parameters to optimize",
                          "pass module.named_parameters() of a module that has some");
  }
  for (const auto& [name, v] : params_) {
    if (!v.defined() || v.value().dtype() != DType::f32) {
      throw InvalidArgument("Optimizer", "parameter '" + name + "' is undefined or not f32",
                            "optimize f32 parameters only");
    }
  }
}

void Optimizer::zero_grad() const {
  for (const auto& [name, v] : params_) v.zero_grad();
}

Sgd::Sgd(NamedVars params, const kernels::SgdOptions& options)
    : Optimizer(std::move(params)), options_(options), velocity_(zeros_like_all(params_)) {}

void Sgd::step(Stream& stream) {
  ++steps_;
  for (std::size_t i = 0; i < params_.size(); ++i) {
    const Var& p = params_[i].second;
    if (p.has_grad()) {
      kernels::sgd_step(stream, p.value(), p.grad(), velocity_[i], options_);
      p.mark_modified();
    }
  }
}

NamedTensors Sgd::state() const {
  NamedTensors out;
  for (std::size_t i = 0; i < params_.size(); ++i) {
    out.emplace_back(params_[i].first + ".velocity", velocity_[i]);
  }
  return out;
}

Adam::Adam(NamedVars params, const kernels::AdamOptions& options)
    : Optimizer(std::move(params)),
      options_(options),
      m_(zeros_like_all(params_)),
      v_(zeros_like_all(params_)) {}

void Adam::step(Stream& stream) {
  ++steps_;
  for (std::size_t i = 0; i < params_.size(); ++i) {
    const Var& p = params_[i].second;
    if (p.has_grad()) {
      kernels::adam_step(stream, p.value(), p.grad(), m_[i], v_[i], steps_, options_);
      p.mark_modified();
    }
  }
}

NamedTensors Adam::state() const {
  NamedTensors out;
  for (std::size_t i = 0; i < params_.size(); ++i) {
    out.emplace_back(params_[i].first + ".exp_avg", m_[i]);
    out.emplace_back(params_[i].first + ".exp_avg_sq", v_[i]);
  }
  return out;
}

float WarmupCosine::at(std::uint32_t step) const {
  if (warmup_steps > 0 && step < warmup_steps) {
    return base_lr * float(step + 1) / float(warmup_steps);
  }
  if (step >= total_steps || total_steps <= warmup_steps) return min_lr;
  const double progress = double(step - warmup_steps) / double(total_steps - warmup_steps);
  return min_lr + float(0.5 * (1.0 + std::cos(std::numbers::pi * progress))) * (base_lr - min_lr);
}

}  // namespace vkjr2::nets
