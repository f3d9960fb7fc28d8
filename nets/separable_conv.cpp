#include <vkjr2/nets/separable_conv.hpp>

namespace vkjr2::nets {

namespace k = kernels;

SeparableConv3x3::SeparableConv3x3(const Device& device, WeightReader& r, const std::string& prefix,
                                   std::int64_t cin, std::int64_t cout, int stride)
    : stride_(stride), groups_(int(cin)) {
  depthwise_ = register_parameter("depthwise_filter",
                                  r.depthwise(device, prefix + "/depthwise_filter", cin));
  pointwise_ = register_parameter("pointwise_filter",
                                  r.conv(device, prefix + "/pointwise_filter", {1, 1, cin, cout}));
  bias_ = register_parameter("bias", r.vec(device, prefix + "/bias", cout));
}

k::Conv2dParams SeparableConv3x3::dw_params(const Shape& x) const {
  k::Conv2dParams dw;
  dw.stride_y = dw.stride_x = stride_;
  dw.pad = k::same_padding(x[2], x[3], 3, 3, stride_, stride_);
  dw.groups = groups_;
  return dw;
}

k::Conv2dParams SeparableConv3x3::pw_params(k::Activation act, float slope) {
  k::Conv2dParams pw;
  pw.activation = act;
  pw.leaky_slope = slope;
  return pw;
}

Shape SeparableConv3x3::mid_shape(const Shape& x) const {
  return k::conv2d_output_shape(x, depthwise_.shape(), dw_params(x));
}

Shape SeparableConv3x3::output_shape(const Shape& x) const {
  const Shape mid = mid_shape(x);
  return Shape{mid[0], out_channels(), mid[2], mid[3]};
}

Var SeparableConv3x3::forward(Tape& t, const Var& x, k::Activation act, float slope,
                              const SeparableExtras& extras) const {
  k::Conv2dParams dw = dw_params(x.shape());
  dw.relu_input = extras.relu_input;
  const Var mid = conv2d(t, x, depthwise_, Var(), dw, &depthwise_plans_);
  return conv2d(t, mid, pointwise_, bias_, pw_params(act, slope), &pointwise_plans_,
                extras.residual, extras.out);
}

k::PlaneLayout SeparableConv3x3::input_layout(const Tape& t, const Shape& x) const {
  return depthwise_plans_.input_layout(t, x, depthwise_, Var(), dw_params(x));
}

}  // namespace vkjr2::nets
