#include <vkjr2/kernels/basic.hpp>
#include <vkjr2/kernels/check.hpp>

#include <string>

namespace vkjr2::kernels {
namespace {

constexpr std::uint32_t kPerGroup = 1024;      // axpy: 256 invocations × 4 floats
constexpr std::uint32_t kVec4PerGroup = 4096;  // fill/copy: 256 invocations × 4 vec4
constexpr std::uint32_t kSumPerGroup = 2048;   // reduce_sum: 256 invocations × 8

struct FillPush {
  std::uint32_t n;
  float value;
};
struct CopyPush {
  std::uint32_t n;
};
struct AxpyPush {
  std::uint32_t n;
  float alpha;
};
struct SumPush {
  std::uint32_t n;
};
static_assert(sizeof(FillPush) <= 128 && sizeof(AxpyPush) <= 128);

}  // namespace

void fill(Stream& stream, const Tensor& dst, float value) {
  static const KernelDef kFill{"fill", {BindingKind::storage}, sizeof(FillPush)};
  const std::uint32_t n = require_f32(dst, "fill", "dst");
  stream.dispatch(kFill, {out(dst)}, FillPush{n, value},
                  groups_1d(div_up(n, kVec4PerGroup), stream.device().info()));
}

void copy(Stream& stream, const Tensor& src, const Tensor& dst) {
  static const KernelDef kCopy{
      "copy", {BindingKind::texel, BindingKind::texel, BindingKind::storage}, sizeof(CopyPush)};
  const std::uint32_t n = require_f32(src, "copy", "src");
  require_f32(dst, "copy", "dst");
  require_same_numel(src, dst, "copy", "src", "dst");
  // vec4 body through an RGBA32F view (its range must be a multiple of 16
  // bytes); below 4 elements the body is empty and the R32F view serves.
  const std::uint32_t body = n / 4 * 4;
  const Arg src4 =
      body > 0 ? texel(src.view(Shape{body}), VK_FORMAT_R32G32B32A32_SFLOAT) : texel(src);
  stream.dispatch(kCopy, {src4, texel(src), out(dst)}, CopyPush{n},
                  groups_1d(div_up(n, kVec4PerGroup), stream.device().info()));
}

void axpy(Stream& stream, float alpha, const Tensor& x, const Tensor& y) {
  static const KernelDef kAxpy{
      "axpy", {BindingKind::texel, BindingKind::storage}, sizeof(AxpyPush)};
  const std::uint32_t n = require_f32(x, "axpy", "x");
  require_f32(y, "axpy", "y");
  require_same_numel(x, y, "axpy", "x", "y");
  stream.dispatch(kAxpy, {texel(x), inout(y)}, AxpyPush{n, alpha},
                  groups_1d(div_up(n, kPerGroup), stream.device().info()));
}

void sum(Stream& stream, const Tensor& x, const Tensor& out_sum) {
  static const KernelDef kReduce{
      "reduce_sum", {BindingKind::texel, BindingKind::storage}, sizeof(SumPush)};
  std::uint32_t n = require_f32(x, "sum", "x");
  if (require_f32(out_sum, "sum", "out") != 1) {
    throw InvalidArgument("sum", "out must have exactly one element, got " + out_sum.shape().str());
  }
  const Device device = stream.device();
  require_subgroup_arithmetic(stream, "sum");
  Tensor current = x;
  for (;;) {
    const std::uint32_t groups = div_up(n, kSumPerGroup);
    Tensor partial = groups == 1 ? out_sum : Tensor::empty(device, Shape{groups});
    stream.dispatch(kReduce, {texel(current), vkjr2::out(partial)}, SumPush{n},
                    groups_1d(groups, device.info()));
    if (groups == 1) return;
    current = partial;
    n = groups;
  }
}

}  // namespace vkjr2::kernels
