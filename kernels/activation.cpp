#include <vkjr2/kernels/activation.hpp>
#include <vkjr2/kernels/check.hpp>
#include <vkjr2/kernels/elementwise.hpp>
#include <vkjr2/kernels/reduce.hpp>

#include "internal/channel_ops.hpp"

namespace vkjr2::kernels {

using detail::unary;
using detail::UnaryOp;

void relu(Stream& stream, const Tensor& x, const Tensor& y) {
  unary(stream, "relu", UnaryOp::relu, x, nullptr, nullptr, y);
}
void relu_backward(Stream& stream, const Tensor& x, const Tensor& dy, const Tensor& dx) {
  unary(stream, "relu_backward", UnaryOp::relu, x, &dy, nullptr, dx);
}

void leaky_relu(Stream& stream, const Tensor& x, float slope, const Tensor& y) {
  unary(stream, "leaky_relu", UnaryOp::leaky_relu, x, nullptr, nullptr, y, slope);
}
void leaky_relu_backward(Stream& stream, const Tensor& x, float slope, const Tensor& dy,
                         const Tensor& dx) {
  unary(stream, "leaky_relu_backward", UnaryOp::leaky_relu, x, &dy, nullptr, dx, slope);
}

void prelu(Stream& stream, const Tensor& x, const Tensor& slope, const Tensor& y) {
  unary(stream, "prelu", UnaryOp::prelu, x, nullptr, &slope, y);
}
void prelu_backward(Stream& stream, const Tensor& x, const Tensor& slope, const Tensor& dy,
                    const Tensor* dx, const Tensor* dslope) {
  if (dx != nullptr) unary(stream, "prelu_backward", UnaryOp::prelu, x, &dy, &slope, *dx);
  if (dslope != nullptr) {
    require_f32(x, "prelu_backward", "x");
    require_f32(dy, "prelu_backward", "dy");
    require_same_shape(x, dy, "prelu_backward", "x", "dy");
    const detail::ChannelGeometry g = detail::channel_geometry(x);
    require_f32(*dslope, "prelu_backward", "dslope");
    require_shape(*dslope, Shape{std::int64_t(g.channels)}, "prelu_backward", "dslope");
    detail::reduce_channels(stream, dy, &x, 2, g.batch, g.channels, g.hw, *dslope);
  }
}

void sigmoid(Stream& stream, const Tensor& x, const Tensor& y) {
  unary(stream, "sigmoid", UnaryOp::sigmoid, x, nullptr, nullptr, y);
}
void sigmoid_backward(Stream& stream, const Tensor& y, const Tensor& dy, const Tensor& dx) {
  unary(stream, "sigmoid_backward", UnaryOp::sigmoid, y, &dy, nullptr, dx);
}

void tanh_activation(Stream& stream, const Tensor& x, const Tensor& y) {
  unary(stream, "tanh_activation", UnaryOp::tanh, x, nullptr, nullptr, y);
}
void tanh_activation_backward(Stream& stream, const Tensor& y, const Tensor& dy, const Tensor& dx) {
  unary(stream, "tanh_activation_backward", UnaryOp::tanh, y, &dy, nullptr, dx);
}

}  // namespace vkjr2::kernels
