#include <vkjr2/kernels/check.hpp>
#include <vkjr2/kernels/fast_div.hpp>
#include <vkjr2/kernels/pool.hpp>

#include <algorithm>
#include <string>

namespace vkjr2::kernels {
namespace {

// Mirrors the push block of shaders/pool_*.comp.
struct PoolPush {
  std::uint32_t planes;
  std::int32_t h, w, oh, ow;
  std::int32_t kh, kw, sh, sw;
  std::int32_t pad_top, pad_left, pad_bottom, pad_right;
  std::uint32_t flag;
  Magic blocks_magic, rows_magic;          // blocks per row, rows per plane of the written tensor
  std::uint32_t y_plane, y_row, y_offset;  // pool_max: y's layout (plain or a padded interior)
};
static_assert(sizeof(PoolPush) <= 128);

struct GlobalPush {
  std::uint32_t planes;  // global_avg: planes; backward: element count
  std::uint32_t hw;
};

constexpr std::uint32_t kGroup = 256;

std::string pool_str(const Pool2d& p) {
  return "kernel " + std::to_string(p.kernel_h) + "x" + std::to_string(p.kernel_w) + ", stride " +
         std::to_string(p.stride_h) + "x" + std::to_string(p.stride_w) + ", padding t/b/l/r " +
         std::to_string(p.pad_top) + "/" + std::to_string(p.pad_bottom) + "/" +
         std::to_string(p.pad_left) + "/" + std::to_string(p.pad_right);
}

std::int64_t out_size(std::int64_t in, std::int32_t k, std::int32_t s, std::int32_t before,
                      std::int32_t after) {
  const std::int64_t span = in + before + after - k;
  return span < 0 ? 0 : span / s + 1;
}

// `written` is the tensor the shader writes (y forward, dx backward).
PoolPush make_push(const Shape& x, const Shape& y, const Pool2d& p, std::uint32_t flag,
                   const Shape& written) {
  return PoolPush{static_cast<std::uint32_t>(x[0] * x[1]),
                  static_cast<std::int32_t>(x[2]),
                  static_cast<std::int32_t>(x[3]),
                  static_cast<std::int32_t>(y[2]),
                  static_cast<std::int32_t>(y[3]),
                  p.kernel_h,
                  p.kernel_w,
                  p.stride_h,
                  p.stride_w,
                  p.pad_top,
                  p.pad_left,
                  p.pad_bottom,
                  p.pad_right,
                  flag,
                  magic(div_up(written[3], 4)),
                  magic(static_cast<std::uint64_t>(written[2])),
                  static_cast<std::uint32_t>(y[2] * y[3]),
                  static_cast<std::uint32_t>(y[3]),
                  0};
}

// Groups for 4 consecutive pixels of one row per invocation.
Groups row_groups(const Shape& s, const DeviceInfo& info) {
  const std::uint64_t items = std::uint64_t(s[0] * s[1] * s[2]) * div_up(s[3], 4);
  return groups_1d(div_up(items, kGroup), info);
}

}  // namespace

Pool2d pool_same(std::int32_t kernel_h, std::int32_t kernel_w, std::int32_t stride_h,
                 std::int32_t stride_w, std::int64_t in_h, std::int64_t in_w) {
  if (kernel_h < 1 || kernel_w < 1 || stride_h < 1 || stride_w < 1 || in_h < 1 || in_w < 1) {
    throw InvalidArgument("pool_same", "kernel, stride and input size must be positive");
  }
  auto split = [](std::int64_t in, std::int32_t k, std::int32_t s, std::int32_t& before,
                  std::int32_t& after) {
    const std::int64_t out = (in + s - 1) / s;
    const std::int64_t total = std::max<std::int64_t>((out - 1) * s + k - in, 0);
    before = static_cast<std::int32_t>(total / 2);
    after = static_cast<std::int32_t>(total - total / 2);
  };
  Pool2d p{kernel_h, kernel_w, stride_h, stride_w, 0, 0, 0, 0};
  split(in_h, kernel_h, stride_h, p.pad_top, p.pad_bottom);
  split(in_w, kernel_w, stride_w, p.pad_left, p.pad_right);
  return p;
}

Pool2d pool_valid(std::int32_t kernel_h, std::int32_t kernel_w, std::int32_t stride_h,
                  std::int32_t stride_w) {
  return Pool2d{kernel_h, kernel_w, stride_h, stride_w, 0, 0, 0, 0};
}

Shape pool_output_shape(const Shape& x, const Pool2d& p) {
  const char* op = "pool2d";
  if (x.rank() != 4) {
    throw InvalidArgument(op, "x " + x.str() + " must be NCHW (rank 4)");
  }
  if (p.kernel_h < 1 || p.kernel_w < 1 || p.stride_h < 1 || p.stride_w < 1) {
    throw InvalidArgument(op, "kernel and stride must be positive, got " + pool_str(p));
  }
  if (p.pad_top < 0 || p.pad_bottom < 0 || p.pad_left < 0 || p.pad_right < 0 ||
      p.pad_top >= p.kernel_h || p.pad_bottom >= p.kernel_h || p.pad_left >= p.kernel_w ||
      p.pad_right >= p.kernel_w) {
    throw InvalidArgument(op, "padding must be in [0, kernel) on each side, got " + pool_str(p),
                          "crop or pad the input with pad() instead");
  }
  const std::int64_t oh = out_size(x[2], p.kernel_h, p.stride_h, p.pad_top, p.pad_bottom);
  const std::int64_t ow = out_size(x[3], p.kernel_w, p.stride_w, p.pad_left, p.pad_right);
  if (oh < 1 || ow < 1) {
    throw InvalidArgument(op, "the window (" + pool_str(p) + ") does not fit input " + x.str(),
                          "use a smaller kernel or padding (pool_same)");
  }
  if (x[0] * x[1] * oh * ow > std::int64_t(INT32_MAX) || x.numel() > std::int64_t(INT32_MAX)) {
    throw InvalidArgument(op, "x " + x.str() + " is too large for 32-bit indices",
                          "split the batch");
  }
  return Shape{x[0], x[1], oh, ow};
}

namespace {

constexpr std::int32_t kMaxUnrolledWindow = 7;  // pool_max: windows up to 7×7 unroll

// pool_max into y (its layout in push), indices when defined.
void run_max_pool(Stream& stream, const Tensor& x, const Pool2d& p, const Tensor& y,
                  const Tensor& indices, const PoolPush& push, const Shape& ys) {
  static const KernelDef k{"pool_max",
                           {BindingKind::texel, BindingKind::storage, BindingKind::storage},
                           sizeof(PoolPush)};
  const bool unrolled = p.kernel_h <= kMaxUnrolledWindow && p.kernel_w <= kMaxUnrolledWindow;
  const bool with_indices = indices.defined();
  stream.dispatch(k, {texel(x), out(y), out(with_indices ? indices : y)}, push,
                  row_groups(ys, stream.device().info()),
                  {unrolled ? std::uint32_t(p.kernel_h) : 0u,
                   unrolled ? std::uint32_t(p.kernel_w) : 0u, with_indices ? 1u : 0u});
}

}  // namespace

void max_pool2d(Stream& stream, const Tensor& x, const Pool2d& p, const Tensor& y,
                const Tensor& indices) {
  const char* op = "max_pool2d";
  require_f32_rank(x, 4, op, "x");
  const Shape ys = pool_output_shape(x.shape(), p);
  require_f32(y, op, "y");
  require_shape(y, ys, op, "y");
  if (indices.defined()) {
    if (indices.dtype() != DType::i32) {
      throw InvalidArgument(op, "indices must be an i32 tensor", "allocate it with DType::i32");
    }
    require_shape(indices, ys, op, "indices");
  }
  run_max_pool(stream, x, p, y, indices, make_push(x.shape(), ys, p, 0, ys), ys);
}

void max_pool2d_into_padded(Stream& stream, const Tensor& x, const Pool2d& p, const Planes& y) {
  const char* op = "max_pool2d_into_padded";
  require_f32_rank(x, 4, op, "x");
  const Shape ys = pool_output_shape(x.shape(), p);
  const PlaneLayout g = y.geometry();
  if (!y.defined() || !(y.shape == ys) || g.top < 0 || g.left < 0 ||
      std::int64_t(g.hp) < g.top + ys[2] || std::int64_t(g.wp) < g.left + ys[3] ||
      y.data.numel() != ys[0] * ys[1] * std::int64_t(g.hp) * std::int64_t(g.wp)) {
    throw InvalidArgument(op,
                          "y must be a padded tensor of the pool's output shape " + ys.str() +
                              (y.defined() ? ", got one of " + y.shape.str() : ", got none"),
                          "make it with Planes::make for the pool's output shape");
  }
  PoolPush push = make_push(x.shape(), ys, p, 0, ys);
  push.y_plane = g.hp * g.wp;
  push.y_row = g.wp;
  push.y_offset = std::uint32_t(g.top) * g.wp + std::uint32_t(g.left);
  run_max_pool(stream, x, p, y.data, Tensor(), push, ys);
}

void max_pool2d_backward(Stream& stream, const Tensor& dy, const Tensor& indices, const Pool2d& p,
                         const Tensor& dx) {
  static const KernelDef k{"pool_max_backward",
                           {BindingKind::texel, BindingKind::texel, BindingKind::storage},
                           sizeof(PoolPush)};
  const char* op = "max_pool2d_backward";
  require_f32_rank(dx, 4, op, "dx");
  const Shape ys = pool_output_shape(dx.shape(), p);
  require_f32(dy, op, "dy");
  require_shape(dy, ys, op, "dy");
  if (!indices.defined() || indices.dtype() != DType::i32) {
    throw InvalidArgument(op, "indices must be the i32 tensor max_pool2d wrote");
  }
  require_shape(indices, ys, op, "indices");
  stream.dispatch(k, {texel(dy), texel(indices, VK_FORMAT_R32_SINT), out(dx)},
                  make_push(dx.shape(), ys, p, 0, dx.shape()),
                  row_groups(dx.shape(), stream.device().info()));
}

void avg_pool2d(Stream& stream, const Tensor& x, const Pool2d& p, bool count_include_pad,
                const Tensor& y) {
  static const KernelDef k{
      "pool_avg", {BindingKind::texel, BindingKind::storage}, sizeof(PoolPush)};
  const char* op = "avg_pool2d";
  require_f32_rank(x, 4, op, "x");
  const Shape ys = pool_output_shape(x.shape(), p);
  require_f32(y, op, "y");
  require_shape(y, ys, op, "y");
  stream.dispatch(k, {texel(x), out(y)}, make_push(x.shape(), ys, p, count_include_pad ? 1 : 0, ys),
                  row_groups(ys, stream.device().info()));
}

void avg_pool2d_backward(Stream& stream, const Tensor& dy, const Pool2d& p, bool count_include_pad,
                         const Tensor& dx) {
  static const KernelDef k{
      "pool_avg_backward", {BindingKind::texel, BindingKind::storage}, sizeof(PoolPush)};
  const char* op = "avg_pool2d_backward";
  require_f32_rank(dx, 4, op, "dx");
  const Shape ys = pool_output_shape(dx.shape(), p);
  require_f32(dy, op, "dy");
  require_shape(dy, ys, op, "dy");
  stream.dispatch(k, {texel(dy), out(dx)},
                  make_push(dx.shape(), ys, p, count_include_pad ? 1 : 0, dx.shape()),
                  row_groups(dx.shape(), stream.device().info()));
}

void global_avg_pool(Stream& stream, const Tensor& x, const Tensor& y) {
  static const KernelDef k{
      "pool_global_avg", {BindingKind::texel, BindingKind::storage}, sizeof(GlobalPush)};
  static const KernelDef k_small{
      "pool_global_avg_small", {BindingKind::texel, BindingKind::storage}, sizeof(GlobalPush)};
  // Planes up to this size: one invocation each (pool_global_avg_small).
  constexpr std::uint32_t kSmallGlobalPlane = 64;
  const char* op = "global_avg_pool";
  require_f32_rank(x, 4, op, "x");
  require_f32(y, op, "y");
  const Shape& s = x.shape();
  require_shape(y, Shape{s[0], s[1], 1, 1}, op, "y");
  const auto planes = static_cast<std::uint32_t>(s[0] * s[1]);
  const auto hw = static_cast<std::uint32_t>(s[2] * s[3]);
  if (hw <= kSmallGlobalPlane) {  // one invocation per plane
    stream.dispatch(k_small, {texel(x), out(y)}, GlobalPush{planes, hw},
                    groups_1d(div_up(planes, 64), stream.device().info()));
    return;
  }
  require_subgroup_arithmetic(stream, op);
  stream.dispatch(k, {texel(x), out(y)}, GlobalPush{planes, hw},
                  groups_1d(planes, stream.device().info()));
}

void global_avg_pool_backward(Stream& stream, const Tensor& dy, const Tensor& dx) {
  static const KernelDef k{
      "pool_global_avg_backward", {BindingKind::texel, BindingKind::storage}, sizeof(GlobalPush)};
  const char* op = "global_avg_pool_backward";
  const std::uint32_t n = require_f32_rank(dx, 4, op, "dx");
  require_f32(dy, op, "dy");
  const Shape& s = dx.shape();
  require_shape(dy, Shape{s[0], s[1], 1, 1}, op, "dy");
  stream.dispatch(k, {texel(dy), out(dx)}, GlobalPush{n, static_cast<std::uint32_t>(s[2] * s[3])},
                  groups_1d(div_up(n, 1024), stream.device().info()));
}

}  // namespace vkjr2::kernels
