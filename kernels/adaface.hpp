// AdaFace margin (Kim et al., "AdaFace: Quality Adaptive Margin for Face
// Recognition", CVPR 2022): the quality-adaptive margin applied to the cosine
// logits of a face-recognition classifier. Two ops:
//
// 1. adaface_scaler: the feature norms ‖z‖ [B] become the per-sample margin
//    scaler ẑ [B] (no gradient: the paper detaches it):
//      n_b = clip(‖z_b‖, 0.001, 100)
//      update (training): μ ← α·mean(n) + (1 − α)·μ, σ ← α·std(n) + (1 − α)·σ
//                         (std unbiased, B ≥ 2; written back in place)
//      ẑ_b = clip(h·(n_b − μ)/(σ + eps), −1, 1)   (with the updated μ, σ)
// 2. adaface_margin: cos [B, C] (cosines between normalized embeddings and
//    class centres) → scaled logits [B, C]:
//      c = clamp(cos, −1 + eps, 1 − eps)
//      j ≠ label[b]: s·c
//      j = label[b]: θ′ = clip(arccos(c) − m·ẑ_b, eps, π − eps)   (g_angle = −m ẑ)
//                    s·(cos θ′ − (m + m·ẑ_b))                    (g_add = m + m ẑ)
//    Computed without acos (cos(θ − δ) expanded; see the shader): the
//    built-in trig functions are too imprecise on some Vulkan devices.
//    Its backward gives d cos = d logits · d logit / d cos with ẑ held fixed;
//    zero where a clamp or clip is active (outside its range).
//
// A label outside [0, C) makes its whole row of logits (and d cos) NaN, as
// kernels::cross_entropy does. NaN inputs propagate.
#pragma once

#include <vkjr2/runtime/stream.hpp>

namespace vkjr2::kernels {

struct AdaFaceParams {
  float m = 0.4f;       // margin
  float h = 0.333f;     // concentration of ẑ (≈ 68 % of samples in [−h, h])
  float s = 64.f;       // logit scale
  float eps = 1e-3f;    // clamp of cos and θ′, and added to σ
  float alpha = 0.01f;  // momentum of the running norm statistics
};

// Throws InvalidArgument unless m in [0, 1], h > 0, s > 0, eps in (0, 0.1] and
// alpha in (0, 1] (all finite). `op` names the caller in the message.
void check_adaface_params(const AdaFaceParams& p, const char* op);

// norms [B] f32 (raw ‖z‖, clipped inside), running_mean and running_std f32
// [1] (read; updated in place when `update`), scaler [B] f32 out.
// update needs B ≥ 2 (the unbiased std of one value is undefined).
void adaface_scaler(Stream& stream, const Tensor& norms, const Tensor& running_mean,
                    const Tensor& running_std, bool update, const AdaFaceParams& p,
                    const Tensor& scaler);

// cos [B, C] f32, labels i32 [B], scaler [B] f32 (from adaface_scaler),
// logits [B, C] f32 out (may not alias cos).
void adaface_margin(Stream& stream, const Tensor& cos, const Tensor& labels, const Tensor& scaler,
                    const AdaFaceParams& p, const Tensor& logits);
// d_logits [B, C] → d_cos [B, C] (may not alias the inputs).
void adaface_margin_backward(Stream& stream, const Tensor& cos, const Tensor& labels,
                             const Tensor& scaler, const Tensor& d_logits, const AdaFaceParams& p,
                             const Tensor& d_cos);

}  // namespace vkjr2::kernels
