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

Var SeparableConv3x3::forward(Tape& t, const Var& x, k::Activation act, float slope) const {
  const Var mid = conv2d(t, x, depthwise_, Var(), dw_params(x.shape()));
  return conv2d(t, mid, pointwise_, bias_, pw_params(act, slope), &pointwise_packed_);
}

void SeparableConv3x3::pack(Stream& s) const { pointwise_packed_.get(s, pointwise_); }

bool SeparableConv3x3::infers(const Tape& t, const Shape& x) const {
  if (t.needs_grad({&depthwise_, &pointwise_, &bias_})) return false;
  const Device& device = t.device();
  return k::conv2d_select(device, x, depthwise_.shape(), dw_params(x)) ==
             k::Conv2dAlgo::depthwise &&
         k::conv2d_select(device, mid_shape(x), pointwise_.shape(),
                          pw_params(k::Activation::none, 0.f)) == k::Conv2dAlgo::pointwise;
}

k::Conv2dPadded SeparableConv3x3::padded_input(Tape& t, const Shape& x) const {
  return k::conv2d_padded_input(t.stream(), x, depthwise_.shape(), dw_params(x));
}

Var SeparableConv3x3::run_padded(Tape& t, const k::Conv2dPadded& xp, bool relu_input,
                                 k::Activation act, float slope, const k::Conv2dPadded* residual,
                                 const k::Conv2dPadded* into) const {
  Stream& s = t.stream();
  k::Conv2dParams dw = dw_params(xp.shape);
  dw.relu_input = relu_input;
  const Tensor mid = Tensor::empty(s.device(), mid_shape(xp.shape));
  k::Conv2dPaddedIo io_dw;
  io_dw.x = &xp;
  k::conv2d_padded(s, nullptr, depthwise_.value(), nullptr, &mid, dw, io_dw);
  k::Conv2dPaddedIo io_pw;
  io_pw.y = into;
  io_pw.residual = residual;
  const k::Conv2dPackedWeight& packed = pointwise_packed_.get(s, pointwise_);
  Tensor y;
  if (into == nullptr) y = Tensor::empty(s.device(), output_shape(xp.shape));
  k::conv2d_padded(s, &mid, pointwise_.value(), &bias_.value(), into == nullptr ? &y : nullptr,
                   pw_params(act, slope), io_pw, &packed);
  return into == nullptr ? t.output(y, false) : Var();
}

}  // namespace vkjr2::nets
