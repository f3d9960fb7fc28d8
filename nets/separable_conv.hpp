// face-api's depthwiseSeparableConv (common/ and tinyYolov2/): a 3×3
// depthwise conv at `stride` with TF's "same" padding (asymmetric for stride
// 2 on even sizes; pad 1 all round at stride 1), then a 1×1 conv + bias and
// an activation. Used by FaceLandmark68Net and TinyFaceDetector.
//
// Two paths: forward() records on the tape (gradients reach x and the
// weights); in inference (infers(): no parameter needs a gradient) the
// run_padded() form reads x from its zero-padded copy (padded_input(),
// written by the producer of x, so no padding pass runs), can apply a ReLU
// to x as it is read, adds a residual in the pointwise epilogue and writes
// its output straight into the next conv's padded input.
#pragma once

#include <vkjr2/kernels/conv2d.hpp>
#include <vkjr2/nets/autograd.hpp>
#include <vkjr2/nets/face_common.hpp>
#include <vkjr2/nets/ops.hpp>

#include <string>

namespace vkjr2::nets {

class SeparableConv3x3 : public Module {
 public:
  // Parameters "depthwise_filter", "pointwise_filter", "bias" from
  // `prefix`/… in r: [3, 3, cin, 1], [1, 1, cin, cout], [cout].
  SeparableConv3x3(const Device& device, WeightReader& r, const std::string& prefix,
                   std::int64_t cin, std::int64_t cout, int stride);

  // act(pw(dw(x)) + bias); slope: LeakyReLU's.
  Var forward(Tape& t, const Var& x, kernels::Activation act, float slope = 0.2f) const;

  // Packs the pointwise filter for the fast conv (again only if it changes).
  void pack(Stream& s) const;
  std::int64_t out_channels() const { return bias_.shape()[0]; }
  // The output shape for x of shape x.
  Shape output_shape(const Shape& x) const;

  // Whether run_padded can run this conv for x of shape x: no parameter
  // needs a gradient, and the two steps run the depthwise and pointwise
  // variants (the ones that read and write padded tensors).
  bool infers(const Tape& t, const Shape& x) const;
  // The depthwise step's zero-padded input for x of shape x (zero-filled),
  // for the producer of x to write into.
  kernels::Conv2dPadded padded_input(Tape& t, const Shape& x) const;

  // Inference (infers()): act(pw(dw(relu?(x))) + bias + residual). x is read
  // from its padded copy xp (padded_input), through a ReLU when relu_input;
  // residual (nullptr: none) is a padded tensor of the output's shape; the
  // output goes into `into` (the next conv's padded input; the result is
  // then undefined), else it is returned.
  Var run_padded(Tape& t, const kernels::Conv2dPadded& xp, bool relu_input, kernels::Activation act,
                 float slope, const kernels::Conv2dPadded* residual,
                 const kernels::Conv2dPadded* into) const;

 private:
  kernels::Conv2dParams dw_params(const Shape& x) const;
  static kernels::Conv2dParams pw_params(kernels::Activation act, float slope);
  Shape mid_shape(const Shape& x) const;

  Var depthwise_, pointwise_, bias_;
  ConvWeightCache pointwise_packed_;
  int stride_, groups_;
};

}  // namespace vkjr2::nets
