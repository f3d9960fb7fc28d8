// face-api's depthwiseSeparableConv (common/ and tinyYolov2/): a 3×3
// depthwise conv at `stride` with TF's "same" padding (asymmetric for stride
// 2 on even sizes; pad 1 all round at stride 1), then a 1×1 conv + bias and
// an activation. Used by FaceLandmark68Net and TinyFaceDetector.
//
// One forward: under a tape that records gradients every activation is a
// plain tensor; in inference the convolutions' plans decide the layouts (the
// depthwise conv reads x from padded planes its producer wrote, and the
// pointwise conv can write its output into the next conv's padded input).
#pragma once

#include <vkjr2/kernels/conv2d.hpp>
#include <vkjr2/nets/autograd.hpp>
#include <vkjr2/nets/face_common.hpp>
#include <vkjr2/nets/ops.hpp>

#include <string>

namespace vkjr2::nets {

// What a block adds around a separable conv's two convs (all optional).
struct SeparableExtras {
  bool relu_input = false;   // x goes through a ReLU first (fused into the depthwise read)
  Var residual;              // added before the activation (a shortcut or a running sum)
  kernels::PlaneLayout out;  // the layout of the output's consumer (ConvPlans::input_layout)
};

class SeparableConv3x3 : public Module {
 public:
  // Parameters "depthwise_filter", "pointwise_filter", "bias" from
  // `prefix`/… in r: [3, 3, cin, 1], [1, 1, cin, cout], [cout].
  SeparableConv3x3(const Device& device, WeightReader& r, const std::string& prefix,
                   std::int64_t cin, std::int64_t cout, int stride);

  // act(pw(dw(relu?(x))) + bias + residual); slope: LeakyReLU's.
  Var forward(Tape& t, const Var& x, kernels::Activation act, float slope = 0.2f,
              const SeparableExtras& extras = {}) const;
  // The layout forward() reads x of shape x in with no padding pass.
  kernels::PlaneLayout input_layout(const Tape& t, const Shape& x) const;

  std::int64_t out_channels() const { return bias_.shape()[0]; }
  // The output shape for x of shape x.
  Shape output_shape(const Shape& x) const;

 private:
  kernels::Conv2dParams dw_params(const Shape& x) const;
  static kernels::Conv2dParams pw_params(kernels::Activation act, float slope);
  Shape mid_shape(const Shape& x) const;

  Var depthwise_, pointwise_, bias_;
  ConvPlans depthwise_plans_, pointwise_plans_;
  int stride_, groups_;
};

}  // namespace vkjr2::nets
