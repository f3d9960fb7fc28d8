#include <vkjr2/kernels/check.hpp>
#include <vkjr2/kernels/mix.hpp>

#include <string>

namespace vkjr2::kernels {
namespace {

struct MixPush {
  std::uint32_t batch, k, plane_h, plane_w, out_h, out_w, write_first2;
  float scale, first2_x, first2_y;
};
static_assert(sizeof(MixPush) <= 128);

}  // namespace

void mix_planes(Stream& stream, const Tensor& planes, const Tensor& mix, const Tensor& out,
                const MixPlanesParams& p, const Tensor* first2) {
  static const KernelDef kMix{
      "mix_planes",
      {BindingKind::texel, BindingKind::texel, BindingKind::storage, BindingKind::storage},
      sizeof(MixPush)};
  const char* op = "mix_planes";
  require_f32_rank(planes, 4, op, "planes");
  require_f32_rank(mix, 2, op, "mix");
  const std::int64_t k = mix.shape()[0];
  if (mix.shape()[1] != k || k < 1)
    throw InvalidArgument(op, "mix must be square [K, K], got " + mix.shape().str());
  if (p.batch < 1) throw InvalidArgument(op, "batch must be >= 1");
  const Shape& s = planes.shape();
  if (s[0] != k * p.batch || s[3] != 2) {
    throw InvalidArgument(op, "planes must be [K*B, H, W, 2] = [" + std::to_string(k * p.batch) +
                                  ", H, W, 2], got " + s.str());
  }
  if (p.out_h < 1 || p.out_w < 1 || p.out_h > s[1] || p.out_w > s[2]) {
    throw InvalidArgument(op, "the output corner " + std::to_string(p.out_h) + "x" +
                                  std::to_string(p.out_w) + " must lie inside the planes " +
                                  s.str());
  }
  require_shape(out, Shape{p.batch, k, p.out_h, p.out_w}, op, "out");
  if (first2 != nullptr) {
    if (k < 2) throw InvalidArgument(op, "first2 needs K >= 2");
    require_shape(*first2, Shape{p.batch, 2, p.out_h, p.out_w}, op, "first2");
  }
  const MixPush push{static_cast<std::uint32_t>(p.batch),
                     static_cast<std::uint32_t>(k),
                     static_cast<std::uint32_t>(s[1]),
                     static_cast<std::uint32_t>(s[2]),
                     static_cast<std::uint32_t>(p.out_h),
                     static_cast<std::uint32_t>(p.out_w),
                     first2 != nullptr ? 1u : 0u,
                     p.scale,
                     p.first2_scale[0],
                     p.first2_scale[1]};
  // Without first2, a one-element placeholder fills binding 3 (never written).
  const Tensor f2 = first2 != nullptr ? *first2 : Tensor::empty(stream.device(), Shape{1});
  const auto points = static_cast<std::uint64_t>(p.out_h * p.out_w);
  stream.dispatch(
      kMix, {texel(planes, VK_FORMAT_R32G32_SFLOAT), texel(mix), vkjr2::out(out), vkjr2::out(f2)},
      push, Groups{div_up(points, 64), static_cast<std::uint32_t>(p.batch), 1});
}

}  // namespace vkjr2::kernels
