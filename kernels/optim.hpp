// Optimizer steps as shaders, in place on f32 parameter tensors. State
// tensors (velocity, first and second moments) have the parameter's shape,
// start at zero and are owned by the caller. grad may not alias any of them.
#pragma once

#include <vkjr2/runtime/stream.hpp>

#include <cstdint>

namespace vkjr2::kernels {

struct SgdOptions {
  float lr = 1e-2f;
  float momentum = 0.9f;
  float weight_decay = 0.f;  // L2, added to the gradient
};
// PyTorch's SGD (dampening 0, Nesterov off): g' = g + wd·p, v = momentum·v + g', p -= lr·v.
void sgd_step(Stream& stream, const Tensor& param, const Tensor& grad, const Tensor& velocity,
              const SgdOptions& options);

struct AdamOptions {
  float lr = 1e-3f;
  float beta1 = 0.9f;
  float beta2 = 0.999f;
  float eps = 1e-8f;
  float weight_decay = 0.f;
  bool decoupled = false;  // true: AdamW (p *= 1 - lr·wd), false: Adam (L2 on the gradient)
};
// One Adam / AdamW step t ≥ 1 (Kingma & Ba 2015; Loshchilov & Hutter 2019),
// bias-corrected with 1 - β^t computed in double on the host:
//   m = β1 m + (1-β1) g;  v = β2 v + (1-β2) g²;
//   p -= (lr / (1-β1^t)) · m / (sqrt(v) / sqrt(1-β2^t) + eps).
void adam_step(Stream& stream, const Tensor& param, const Tensor& grad, const Tensor& m,
               const Tensor& v, std::uint32_t step, const AdamOptions& options);

}  // namespace vkjr2::kernels
