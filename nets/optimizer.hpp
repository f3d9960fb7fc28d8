// Optimizers over a Module's parameters (update shaders from kernels/optim)
// and learning-rate schedules.
//
// State (momentum, Adam moments, the step count) lives on the device and is
// exposed by name so a checkpoint can save and restore it bit-exactly
// (nets/checkpoint.hpp).
#pragma once

#include <vkjr2/kernels/optim.hpp>
#include <vkjr2/nets/autograd.hpp>

#include <cstdint>
#include <string>
#include <vector>

namespace vkjr2::nets {

using NamedVars = std::vector<std::pair<std::string, Var>>;
using NamedTensors = std::vector<std::pair<std::string, Tensor>>;

class Optimizer {
 public:
  explicit Optimizer(NamedVars params);
  virtual ~Optimizer() = default;
  Optimizer(const Optimizer&) = delete;
  Optimizer& operator=(const Optimizer&) = delete;

  // Applies one update to every parameter that has a gradient (others are
  // left untouched, their state too) on `stream`; counts the step.
  virtual void step(Stream& stream) = 0;
  void zero_grad() const;

  virtual float lr() const = 0;
  virtual void set_lr(float lr) = 0;
  std::uint32_t steps() const noexcept { return steps_; }
  void set_steps(std::uint32_t steps) noexcept { steps_ = steps; }

  // Device state tensors by name ("<param>.<slot>"), for checkpoints.
  virtual NamedTensors state() const = 0;
  const NamedVars& params() const noexcept { return params_; }

 protected:
  NamedVars params_;
  std::uint32_t steps_ = 0;
};

// PyTorch's SGD with momentum (kernels::sgd_step).
class Sgd : public Optimizer {
 public:
  Sgd(NamedVars params, const kernels::SgdOptions& options);
  void step(Stream& stream) override;
  float lr() const override { return options_.lr; }
  void set_lr(float lr) override { options_.lr = lr; }
  NamedTensors state() const override;

 private:
  kernels::SgdOptions options_;
  std::vector<Tensor> velocity_;
};

// Adam, or AdamW with options.decoupled (kernels::adam_step).
class Adam : public Optimizer {
 public:
  Adam(NamedVars params, const kernels::AdamOptions& options);
  void step(Stream& stream) override;
  float lr() const override { return options_.lr; }
  void set_lr(float lr) override { options_.lr = lr; }
  NamedTensors state() const override;

 private:
  kernels::AdamOptions options_;
  std::vector<Tensor> m_, v_;
};

// Linear warm-up (base_lr·(step + 1)/warmup_steps) for warmup_steps, then cosine decay to
// min_lr at total_steps (held there after). step counts from 0.
struct WarmupCosine {
  float base_lr = 1e-3f;
  float min_lr = 0.f;
  std::uint32_t warmup_steps = 0;
  std::uint32_t total_steps = 1;
  float at(std::uint32_t step) const;
};

}  // namespace vkjr2::nets
