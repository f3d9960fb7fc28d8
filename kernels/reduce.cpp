#include <vkjr2/kernels/basic.hpp>
#include <vkjr2/kernels/check.hpp>
#include <vkjr2/kernels/elementwise.hpp>
#include <vkjr2/kernels/reduce.hpp>

#include <algorithm>
#include <string>

#include "internal/channel_ops.hpp"

namespace vkjr2::kernels {
namespace {

constexpr std::uint32_t kPerGroup = 1024;  // elementwise: 256 invocations × 4
constexpr std::uint32_t kMaxChunk = 4096;  // max_all: elements per row of the first pass

struct RowsPush {
  std::uint32_t rows, k;
};
struct RowsGradPush {
  std::uint32_t n, k;
};
struct MaxPush {
  std::uint32_t rows, k, n, global_index;
};
static_assert(sizeof(MaxPush) <= 128);

struct RowGeometry {
  std::uint32_t rows, k;
};

RowGeometry rows_of(const Tensor& x, const Tensor& out, const char* op, const char* out_name) {
  const std::uint32_t n = require_f32(x, op, "x");
  const auto k = std::uint32_t(x.shape()[-1]);
  const std::uint32_t rows = n / k;
  require_f32(out, op, out_name);
  if (out.numel() != std::int64_t(rows)) {
    throw InvalidArgument(op, std::string(out_name) + " " + out.shape().str() + " has " +
                                  std::to_string(out.numel()) +
                                  " elements, expected one per row of x " + x.shape().str() + " (" +
                                  std::to_string(rows) + ")");
  }
  return {rows, k};
}

void rows_forward(Stream& stream, std::uint32_t op, const char* name, const Tensor& x,
                  const Tensor& out) {
  static const KernelDef k{
      "reduce_rows", {BindingKind::texel, BindingKind::storage}, sizeof(RowsPush)};
  require_subgroup_arithmetic(stream, name);
  const RowGeometry g = rows_of(x, out, name, "out");
  stream.dispatch(k, {texel(x), vkjr2::out(out)}, RowsPush{g.rows, g.k},
                  subgroup_row_groups(stream, g.rows, name), {op});
}

void rows_backward(Stream& stream, std::uint32_t op, const char* name, const Tensor& dy,
                   const Tensor& dx, const Tensor* x, const Tensor* y, std::uint32_t k_len) {
  static const KernelDef k{
      "reduce_rows_grad",
      {BindingKind::texel, BindingKind::texel, BindingKind::texel, BindingKind::storage},
      sizeof(RowsGradPush)};
  const std::uint32_t n = require_f32(dx, name, "dx");
  const Tensor& xs = x != nullptr ? *x : dy;
  const Tensor& ys = y != nullptr ? *y : dy;
  stream.dispatch(k, {texel(dy), texel(xs), texel(ys), vkjr2::out(dx)}, RowsGradPush{n, k_len},
                  groups_1d(div_up(n, kPerGroup), stream.device().info()), {op});
}

void rows_backward_checked(Stream& stream, std::uint32_t op, const char* name, const Tensor& dy,
                           const Tensor& dx) {
  const RowGeometry g = rows_of(dx, dy, name, "dy");
  rows_backward(stream, op, name, dy, dx, nullptr, nullptr, g.k);
}

void max_pass(Stream& stream, const Tensor& x, const Tensor* idx_in, std::uint32_t rows,
              std::uint32_t k_len, std::uint32_t n, bool global_index, const Tensor& value,
              const Tensor& index) {
  static const KernelDef k{
      "reduce_max",
      {BindingKind::texel, BindingKind::texel, BindingKind::storage, BindingKind::storage},
      sizeof(MaxPush)};
  // Without an index input, x stands in for the unused binding.
  const Arg idx =
      idx_in != nullptr ? texel(*idx_in, VK_FORMAT_R32_SINT) : texel(x, VK_FORMAT_R32_SINT);
  stream.dispatch(k, {texel(x), idx, out(value), out(index)},
                  MaxPush{rows, k_len, n, global_index ? 1u : 0u},
                  subgroup_row_groups(stream, rows, "reduce_max"), {idx_in != nullptr ? 1u : 0u});
}

void require_index(const Tensor& index, std::int64_t count, const char* op) {
  if (!index.defined() || index.dtype() != DType::i32) {
    throw InvalidArgument(op, "index must be an i32 tensor");
  }
  if (index.numel() != count) {
    throw InvalidArgument(op, "index " + index.shape().str() + " has " +
                                  std::to_string(index.numel()) + " elements, expected " +
                                  std::to_string(count));
  }
}

}  // namespace

void sum_rows(Stream& stream, const Tensor& x, const Tensor& out) {
  rows_forward(stream, 0, "sum_rows", x, out);
}
void mean_rows(Stream& stream, const Tensor& x, const Tensor& out) {
  rows_forward(stream, 1, "mean_rows", x, out);
}
void l2norm_rows(Stream& stream, const Tensor& x, const Tensor& out) {
  rows_forward(stream, 2, "l2norm_rows", x, out);
}

void sum_rows_backward(Stream& stream, const Tensor& dy, const Tensor& dx) {
  rows_backward_checked(stream, 0, "sum_rows_backward", dy, dx);
}
void mean_rows_backward(Stream& stream, const Tensor& dy, const Tensor& dx) {
  rows_backward_checked(stream, 1, "mean_rows_backward", dy, dx);
}
void l2norm_rows_backward(Stream& stream, const Tensor& x, const Tensor& y, const Tensor& dy,
                          const Tensor& dx) {
  const char* op = "l2norm_rows_backward";
  const RowGeometry g = rows_of(x, y, op, "y");
  rows_of(x, dy, op, "dy");
  require_f32(dx, op, "dx");
  require_same_shape(x, dx, op, "x", "dx");
  rows_backward(stream, 2, op, dy, dx, &x, &y, g.k);
}

void sum_all(Stream& stream, const Tensor& x, const Tensor& out) { sum(stream, x, out); }

void mean_all(Stream& stream, const Tensor& x, const Tensor& out) {
  const std::uint32_t n = require_f32(x, "mean_all", "x");
  if (require_f32(out, "mean_all", "out") != 1) {
    throw InvalidArgument("mean_all",
                          "out must have exactly one element, got " + out.shape().str());
  }
  Tensor total = Tensor::empty(stream.device(), Shape{1});
  sum(stream, x, total);
  scale_shift(stream, total, float(1.0 / double(n)), 0.f, out);
}

void sum_all_backward(Stream& stream, const Tensor& dy, const Tensor& dx) {
  const std::uint32_t n = require_f32(dx, "sum_all_backward", "dx");
  require_shape(dy, Shape{1}, "sum_all_backward", "dy");
  rows_backward(stream, 0, "sum_all_backward", dy, dx, nullptr, nullptr, n);
}
void mean_all_backward(Stream& stream, const Tensor& dy, const Tensor& dx) {
  const std::uint32_t n = require_f32(dx, "mean_all_backward", "dx");
  require_shape(dy, Shape{1}, "mean_all_backward", "dy");
  rows_backward(stream, 1, "mean_all_backward", dy, dx, nullptr, nullptr, n);
}

void max_rows(Stream& stream, const Tensor& x, const Tensor& value, const Tensor& index) {
  require_subgroup_arithmetic(stream, "max_rows");
  const RowGeometry g = rows_of(x, value, "max_rows", "value");
  require_index(index, g.rows, "max_rows");
  max_pass(stream, x, nullptr, g.rows, g.k, g.rows * g.k, false, value, index);
}

void max_all(Stream& stream, const Tensor& x, const Tensor& value, const Tensor& index) {
  require_subgroup_arithmetic(stream, "max_all");
  std::uint32_t n = require_f32(x, "max_all", "x");
  if (require_f32(value, "max_all", "value") != 1) {
    throw InvalidArgument("max_all",
                          "value must have exactly one element, got " + value.shape().str());
  }
  require_index(index, 1, "max_all");
  const Device device = stream.device();
  Tensor current = x;
  Tensor current_index;
  for (;;) {
    const std::uint32_t rows = div_up(n, kMaxChunk);
    const bool last = rows == 1;
    Tensor v = last ? value : Tensor::empty(device, Shape{rows});
    Tensor i = last ? index : Tensor::empty(device, Shape{rows}, DType::i32);
    max_pass(stream, current, current_index.defined() ? &current_index : nullptr, rows,
             std::min(n, kMaxChunk), n, true, v, i);
    if (last) return;
    current = v;
    current_index = i;
    n = rows;
  }
}

void sum_channels(Stream& stream, const Tensor& x, const Tensor& out) {
  require_f32(x, "sum_channels", "x");
  const detail::ChannelGeometry g = detail::channel_geometry(x);
  require_f32(out, "sum_channels", "out");
  require_shape(out, Shape{std::int64_t(g.channels)}, "sum_channels", "out");
  detail::reduce_channels(stream, x, nullptr, 0, g.batch, g.channels, g.hw, out);
}

}  // namespace vkjr2::kernels
