#include <vkjr2/kernels/check.hpp>
#include <vkjr2/kernels/fast_div.hpp>
#include <vkjr2/kernels/resize.hpp>

#include <array>
#include <string>

namespace vkjr2::kernels {
namespace {

// Mirrors the push block of shaders/resize.comp.
struct ResizePush {
  std::uint32_t planes;
  std::int32_t in_h, in_w, out_h, out_w;
  std::uint32_t mode;
  float scale_h, scale_w;
  Magic blocks_magic, rows_magic;  // blocks per row, rows per plane of the written tensor
  std::int32_t src_h, src_w;       // the source planes in the canvas (forward)
  std::int32_t src_top, src_left;  // where they sit
};
static_assert(sizeof(ResizePush) <= 128);

float axis_scale(ResizeMode mode, std::int64_t in, std::int64_t out) {
  if (mode == ResizeMode::bilinear_align_corners) {
    return out > 1 ? static_cast<float>(in - 1) / static_cast<float>(out - 1) : 0.f;
  }
  return static_cast<float>(in) / static_cast<float>(out);
}

// in: the sampled canvas (the source itself, or the source zero-padded to in's
// H × W); src: the source planes' height, width, top and left in it.
void dispatch_resize(Stream& stream, const Tensor& src, const Tensor& dst, const Shape& in,
                     const Shape& out, ResizeMode mode, bool backward,
                     std::array<std::int64_t, 4> src_at) {
  static const KernelDef k{
      "resize", {BindingKind::texel, BindingKind::storage}, sizeof(ResizePush)};
  if (static_cast<std::uint32_t>(mode) > 3) {
    throw InvalidArgument(backward ? "resize_backward" : "resize",
                          "unknown mode " + std::to_string(static_cast<std::uint32_t>(mode)));
  }
  // One invocation per 4 consecutive pixels of one row of the written tensor.
  const Shape& w = backward ? in : out;
  const ResizePush push{static_cast<std::uint32_t>(in[0] * in[1]),
                        static_cast<std::int32_t>(in[2]),
                        static_cast<std::int32_t>(in[3]),
                        static_cast<std::int32_t>(out[2]),
                        static_cast<std::int32_t>(out[3]),
                        static_cast<std::uint32_t>(mode),
                        axis_scale(mode, in[2], out[2]),
                        axis_scale(mode, in[3], out[3]),
                        magic(div_up(w[3], 4)),
                        magic(static_cast<std::uint64_t>(w[2])),
                        static_cast<std::int32_t>(src_at[0]),
                        static_cast<std::int32_t>(src_at[1]),
                        static_cast<std::int32_t>(src_at[2]),
                        static_cast<std::int32_t>(src_at[3])};
  const std::uint64_t items = std::uint64_t(w[0] * w[1] * w[2]) * div_up(w[3], 4);
  stream.dispatch(k, {texel(src), vkjr2::out(dst)}, push,
                  groups_1d(div_up(items, 256), stream.device().info()),
                  {backward ? 1u : 0u, mode == ResizeMode::nearest ? 1u : 0u});
}

// Mirrors the push block of shaders/resize_into_padded.comp.
struct IntoPaddedPush {
  std::uint32_t channels;
  std::int32_t in_h, in_w, out_h, out_w;
  std::uint32_t mode;
  float scale_h, scale_w;
  Magic blocks_magic;
  std::int32_t src_h, src_w, src_top, src_left;
  std::uint32_t hp, wp, top, left;
};
static_assert(sizeof(IntoPaddedPush) <= 128);

void require_canvas(const char* op, const Tensor& x, const ResizeCanvas& c) {
  const std::int64_t h = x.shape()[2], w = x.shape()[3];
  if (c.top < 0 || c.left < 0 || c.top + h > c.height || c.left + w > c.width ||
      c.height > INT32_MAX || c.width > INT32_MAX) {
    throw InvalidArgument(op,
                          "canvas " + std::to_string(c.height) + "×" + std::to_string(c.width) +
                              " does not hold x " + x.shape().str() + " at (" +
                              std::to_string(c.top) + ", " + std::to_string(c.left) + ")",
                          "pass a canvas that holds x at a non-negative (top, left): the padded "
                          "size and the padding before x");
  }
}

void require_batch_match(const Tensor& a, const Tensor& b, const char* op, const char* a_name,
                         const char* b_name) {
  if (a.shape()[0] != b.shape()[0] || a.shape()[1] != b.shape()[1]) {
    throw InvalidArgument(op, std::string(a_name) + " " + a.shape().str() + " and " + b_name + " " +
                                  b.shape().str() + " differ in N or C");
  }
  if (a.numel() > INT32_MAX || b.numel() > INT32_MAX) {
    throw InvalidArgument(op, "tensors over 2^31 elements are not supported", "split the batch");
  }
}

}  // namespace

void resize(Stream& stream, const Tensor& x, ResizeMode mode, const Tensor& y) {
  const char* op = "resize";
  require_f32_rank(x, 4, op, "x");
  require_f32_rank(y, 4, op, "y");
  require_batch_match(x, y, op, "x", "y");
  dispatch_resize(stream, x, y, x.shape(), y.shape(), mode, false,
                  {x.shape()[2], x.shape()[3], 0, 0});
}

void resize_zero_padded(Stream& stream, const Tensor& x, const ResizeCanvas& canvas,
                        ResizeMode mode, const Tensor& y) {
  const char* op = "resize_zero_padded";
  require_f32_rank(x, 4, op, "x");
  require_f32_rank(y, 4, op, "y");
  require_batch_match(x, y, op, "x", "y");
  require_canvas(op, x, canvas);
  const std::int64_t h = x.shape()[2], w = x.shape()[3];
  const auto& c = canvas;
  const Shape in{x.shape()[0], x.shape()[1], c.height, c.width};
  dispatch_resize(stream, x, y, in, y.shape(), mode, false, {h, w, c.top, c.left});
}

void resize_into_padded(Stream& stream, const Tensor& x, const ResizeCanvas& canvas,
                        ResizeMode mode, const Tensor& scale, const Tensor& shift, const Planes& y,
                        const Tensor* nonfinite) {
  static const KernelDef k{"resize_into_padded",
                           {BindingKind::texel, BindingKind::texel, BindingKind::texel,
                            BindingKind::storage, BindingKind::storage},
                           sizeof(IntoPaddedPush)};
  const char* op = "resize_into_padded";
  require_f32_rank(x, 4, op, "x");
  require_canvas(op, x, canvas);
  if (!y.defined() || y.shape.rank() != 4) {
    throw InvalidArgument(op, "y is not a padded tensor",
                          "pass planes of the network input's shape (Planes::make)");
  }
  const Shape& ys = y.shape;
  const PlaneLayout yg = y.geometry();
  const std::int64_t planes = ys[0] * ys[1], oh = ys[2], ow = ys[3];
  if (x.shape()[0] != ys[0] || x.shape()[1] != ys[1]) {
    throw InvalidArgument(op, "x " + x.shape().str() + " and y " + ys.str() + " differ in N or C");
  }
  if (x.numel() > INT32_MAX || y.data.numel() > INT32_MAX || ys[0] > 65535) {
    throw InvalidArgument(op,
                          "x " + x.shape().str() + " or y " + ys.str() +
                              " is too large (2^31 elements, 65535 images at most)",
                          "split the batch");
  }
  if (oh < 1 || ow < 1 || yg.top < 0 || yg.left < 0 || yg.top + oh > yg.hp ||
      yg.left + ow > yg.wp || planes * yg.hp * yg.wp > y.data.numel()) {
    throw InvalidArgument(op,
                          "padded planes " + std::to_string(yg.hp) + "×" + std::to_string(yg.wp) +
                              " (data " + y.data.shape().str() + ") do not hold y " + ys.str() +
                              " at (" + std::to_string(yg.top) + ", " + std::to_string(yg.left) +
                              ")",
                          "make y with Planes::make for y's shape");
  }
  if (require_f32(scale, op, "scale") != std::uint32_t(ys[1]) ||
      require_f32(shift, op, "shift") != std::uint32_t(ys[1])) {
    throw InvalidArgument(op, "scale " + scale.shape().str() + " and shift " + shift.shape().str() +
                                  " must hold one value per channel (" + std::to_string(ys[1]) +
                                  ")");
  }
  if (nonfinite != nullptr && require_f32(*nonfinite, op, "nonfinite") != 1) {
    throw InvalidArgument(op, "nonfinite must have one element, got " + nonfinite->shape().str());
  }
  if (static_cast<std::uint32_t>(mode) > 3) {
    throw InvalidArgument(op, "unknown mode " + std::to_string(static_cast<std::uint32_t>(mode)));
  }
  const std::uint64_t blocks_x = div_up(std::uint64_t(ow), 4);
  const IntoPaddedPush push{static_cast<std::uint32_t>(ys[1]),
                            static_cast<std::int32_t>(canvas.height),
                            static_cast<std::int32_t>(canvas.width),
                            static_cast<std::int32_t>(oh),
                            static_cast<std::int32_t>(ow),
                            static_cast<std::uint32_t>(mode),
                            axis_scale(mode, canvas.height, oh),
                            axis_scale(mode, canvas.width, ow),
                            magic(blocks_x),
                            static_cast<std::int32_t>(x.shape()[2]),
                            static_cast<std::int32_t>(x.shape()[3]),
                            static_cast<std::int32_t>(canvas.top),
                            static_cast<std::int32_t>(canvas.left),
                            yg.hp,
                            yg.wp,
                            static_cast<std::uint32_t>(yg.top),
                            static_cast<std::uint32_t>(yg.left)};
  const bool store4 = ow % 4 == 0 && yg.wp % 4 == 0 && yg.left % 4 == 0;
  const std::uint64_t items = std::uint64_t(oh) * blocks_x;
  const std::uint32_t lanes = group_lanes(items, stream.device().traits().min_workgroups);
  Groups g = groups_1d(div_up(items, lanes), stream.device().info());
  g.z = static_cast<std::uint32_t>(ys[0]);
  stream.dispatch(k,
                  {texel(x), texel(scale), texel(shift), vkjr2::out(y.data),
                   vkjr2::out(nonfinite != nullptr ? *nonfinite : y.data)},
                  push, g,
                  {mode == ResizeMode::nearest ? 1u : 0u, store4 ? 1u : 0u,
                   nonfinite != nullptr ? 1u : 0u, lanes});
}

void resize_backward(Stream& stream, const Tensor& dy, ResizeMode mode, const Tensor& dx) {
  const char* op = "resize_backward";
  require_f32_rank(dy, 4, op, "dy");
  require_f32_rank(dx, 4, op, "dx");
  require_batch_match(dx, dy, op, "dx", "dy");
  dispatch_resize(stream, dy, dx, dx.shape(), dy.shape(), mode, true,
                  {dx.shape()[2], dx.shape()[3], 0, 0});
}

}  // namespace vkjr2::kernels
