// AdaFace margin head (Kim et al., "AdaFace: Quality Adaptive Margin for Face
// Recognition", CVPR 2022) for training a face embedder.
//
//   cos[b, j] = ⟨z_b/‖z_b‖, W_j/‖W_j‖⟩        (W [D, C], columns = class centres)
//   ẑ_b = clip(h·(clip(‖z_b‖, 0.001, 100) − μ)/(σ + eps), −1, 1)   (detached)
//   logits = s·cos, with the label column s·(cos(θ − m ẑ) − m − m ẑ)
//   (kernels/adaface.hpp has the clamps and clips). Apply nets::cross_entropy
//   to the logits for the loss.
//
// Training mode updates the running μ, σ (buffers, α = 0.01, start 20 and 100)
// with the batch mean and unbiased std of the clipped norms before ẑ is
// formed, as the official implementation does; eval mode keeps them fixed.
// Gradients reach the embeddings (through the normalization) and W; the
// norm's use in ẑ carries none, as in the paper.
//
// Names follow the official PyTorch module: "kernel" [D, C], "batch_mean" and
// "batch_std" [1]. A zero embedding or zero class column gives NaN (its
// normalization divides by zero, as in the official code).
#pragma once

#include <vkjr2/kernels/adaface.hpp>
#include <vkjr2/nets/ops.hpp>

#include <cstdint>

namespace vkjr2::nets {

// m, h, s, eps, alpha (defaults: the paper's 0.4, 0.333, 64, 1e-3, 0.01).
using AdaFaceOptions = kernels::AdaFaceParams;

class AdaFaceHead : public Module {
 public:
  // W starts as the official one does: uniform(−1, 1) from `seed`, each
  // column scaled to unit norm.
  AdaFaceHead(const Device& device, int embedding_dim, int classes, std::uint32_t seed,
              const AdaFaceOptions& options = {});

  // embeddings [B, D] (not normalized), labels i32 [B] in [0, C) (a label
  // outside gives a NaN row) → margin logits [B, C]. Training mode needs B ≥ 2.
  Var forward(Tape& t, const Var& embeddings, const Tensor& labels) const;
  // cos [B, C] between the normalized embeddings and class centres, no margin
  // and no scale (inference, accuracy); differentiable.
  Var cosine(Tape& t, const Var& embeddings) const;

  int embedding_dim() const { return int(weight.shape()[0]); }
  int classes() const { return int(weight.shape()[1]); }

  Var weight;                     // parameter [D, C] ("kernel")
  Var running_mean, running_std;  // buffers [1] ("batch_mean", "batch_std")
  AdaFaceOptions options;
};

}  // namespace vkjr2::nets
