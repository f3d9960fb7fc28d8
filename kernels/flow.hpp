// Dense registration: windowed Lucas–Kanade steps that move a displacement
// field until an image, warped by it, matches a reference (the tilt of a
// turbulent frame against the frames' mean, jr2/turbulence.hpp).
#pragma once

#include <vkjr2/runtime/stream.hpp>

namespace vkjr2::kernels {

struct LucasKanade {
  // The window: a box mean of 2·radius + 1 pixels applied twice along each
  // axis (triangular weights over 4·radius + 1 pixels, clipped at the image
  // border). A plain box would let the coupled update below amplify
  // the flow's fine-scale errors (its frequency response goes negative);
  // the triangle's does not.
  int radius = 3;
  // A pixel whose window's structure tensor has a smaller eigenvalue (mean
  // squared gradient, in intensity units² per pixel²) keeps its flow: the
  // window is too flat to fix both components.
  float min_eigenvalue = 1e-5f;
};

// One Gauss–Newton step of dense Lucas–Kanade registration.
//   ref:  R×1×H×W, R = 1 (one reference for every image) or N
//   img:  N×1×H×W
//   flow_in, flow_out: N×2×H×W (dx, dy in pixels; img(x + flow(x)) ≈ ref(x))
//   min_eig: N×1×H×W, the smaller eigenvalue of each window's mean
//            structure tensor (the registration's confidence), or an empty Tensor
// With g = ∇ref (central differences, the border row repeated) and
// e = img(x + flow_in(x)) − ref(x) (bilinear), window means S = ⟨m g gᵀ⟩,
// b = ⟨m g e⟩, m = 0 where x + flow_in(x) lies outside the image and 1
// elsewhere, give flow_out = flow_in − S⁻¹ b where the smaller eigenvalue
// of S reaches p.min_eigenvalue, flow_in elsewhere. Each pixel's residual
// uses its own flow, so the window couples neighbouring flows: iterated,
// the field converges to a smooth registration (the tilt field is smooth).
// flow_out may not alias flow_in. f32.
void lucas_kanade_step(Stream& stream, const Tensor& ref, const Tensor& img, const Tensor& flow_in,
                       const Tensor& flow_out, const Tensor& min_eig, const LucasKanade& p = {});

}  // namespace vkjr2::kernels
