#include <vkjr2/kernels/check.hpp>
#include <vkjr2/kernels/metrics.hpp>

#include <array>
#include <cmath>
#include <string>

namespace vkjr2::kernels {
namespace {

constexpr int kWindow = 11;     // Wang et al. 2004: 11×11 Gaussian window,
constexpr double kSigma = 1.5;  // σ = 1.5,
constexpr double kK1 = 0.01;    // C1 = (K1 L)²,
constexpr double kK2 = 0.03;    // C2 = (K2 L)².

// Mirrors the push block of shaders/ssim_*.comp.
struct SsimPush {
  std::uint32_t planes, channels;
  std::int32_t h, w;
  float c1, c2;
  std::array<float, kWindow> g;
};
static_assert(sizeof(SsimPush) <= 128);

// Mirror shaders/psnr_partial.comp and psnr_finish.comp.
struct PartialPush {
  std::uint32_t groups, chunks, count;
};
struct FinishPush {
  std::uint32_t images, chunks;
  float denominator, range_sq;
};
constexpr std::uint32_t kChunk = 4096;  // elements per psnr_partial workgroup

constexpr BindingKind kT = BindingKind::texel;
constexpr BindingKind kS = BindingKind::storage;

void require_range(float data_range, const char* op) {
  if (!(data_range > 0.f) || !std::isfinite(data_range)) {
    throw InvalidArgument(
        op, "data_range must be positive and finite, got " + std::to_string(data_range),
        "pass 1 for images in [0, 1], 255 for 8-bit images");
  }
}

// Checks a pair of NCHW images and a per-image tensor of N elements.
void require_pair(const Tensor& a, const Tensor& b, const Tensor& per_image, const char* op,
                  const char* a_name, const char* b_name, const char* per_name) {
  require_f32_rank(a, 4, op, a_name);
  require_f32(b, op, b_name);
  require_same_shape(a, b, op, a_name, b_name);
  if (a.numel() > INT32_MAX) {
    throw InvalidArgument(
        op, std::string(a_name) + " " + a.shape().str() + " has more than 2^31 elements",
        "split the batch");
  }
  if (require_f32(per_image, op, per_name) != a.shape()[0]) {
    throw InvalidArgument(op, std::string(per_name) + " " + per_image.shape().str() +
                                  " must have N = " + std::to_string(a.shape()[0]) +
                                  " elements (one per image)");
  }
}

SsimPush ssim_push(const Shape& s, float data_range, const char* op) {
  if (s[2] < kWindow || s[3] < kWindow) {
    throw InvalidArgument(op, "images " + s.str() + " are smaller than the 11×11 SSIM window",
                          "SSIM needs H, W ≥ 11");
  }
  SsimPush p{};
  p.planes = static_cast<std::uint32_t>(s[0] * s[1]);
  p.channels = static_cast<std::uint32_t>(s[1]);
  p.h = static_cast<std::int32_t>(s[2]);
  p.w = static_cast<std::int32_t>(s[3]);
  const double c1 = kK1 * data_range, c2 = kK2 * data_range;
  p.c1 = static_cast<float>(c1 * c1);
  p.c2 = static_cast<float>(c2 * c2);
  std::array<double, kWindow> g{};
  double total = 0;
  for (int k = 0; k < kWindow; ++k) {
    const double d = k - kWindow / 2;  // NOLINT(bugprone-integer-division): centre tap, exact
    g[std::size_t(k)] = std::exp(-d * d / (2 * kSigma * kSigma));
    total += g[std::size_t(k)];
  }
  // The normalized 2-D window is the outer product of the normalized 1-D one.
  for (int k = 0; k < kWindow; ++k)
    p.g[std::size_t(k)] = static_cast<float>(g[std::size_t(k)] / total);
  return p;
}

constexpr VkFormat kRgba = VK_FORMAT_R32G32B32A32_SFLOAT;

// Pass 1 output: the horizontally filtered x, y, x², y² (t4, one vec4 per
// pixel) and xy (t1), each [planes][H][W − 10].
struct Horizontal {
  Tensor t4, t1;
};

Horizontal ssim_horizontal(Stream& stream, const Tensor& x, const Tensor& y, const SsimPush& p) {
  static const KernelDef k{"ssim_h", {kT, kT, kS, kS}, sizeof(SsimPush)};
  const std::int64_t wv = p.w - 10;
  Horizontal t{Tensor::empty(stream.device(), Shape{p.planes, p.h, wv, 4}),
               Tensor::empty(stream.device(), Shape{p.planes, p.h, wv})};
  const std::uint64_t items = std::uint64_t(p.planes) * std::uint64_t(p.h) * div_up(wv, 8);
  stream.dispatch(k, {texel(x), texel(y), out(t.t4), out(t.t1)}, p,
                  groups_1d(div_up(items, 256), stream.device().info()));
  return t;
}

// Pass 2: vertical filter and the SSIM map [planes][H'][W'] (mode 0) or the
// vec4 gradient terms [planes][H'][W'][4] (mode 1).
Tensor ssim_vertical(Stream& stream, const Horizontal& t, const Tensor& d_ssim, const SsimPush& p,
                     std::uint32_t mode) {
  static const KernelDef k{"ssim_v", {kT, kT, kT, kS}, sizeof(SsimPush)};
  const std::int64_t hv = p.h - 10, wv = p.w - 10;
  Tensor result = mode == 0 ? Tensor::empty(stream.device(), Shape{p.planes, hv, wv})
                            : Tensor::empty(stream.device(), Shape{p.planes, hv, wv, 4});
  const std::uint64_t items = std::uint64_t(p.planes) * div_up(hv, 8) * std::uint64_t(wv);
  stream.dispatch(k, {texel(t.t4, kRgba), texel(t.t1), texel(d_ssim), out(result)}, p,
                  groups_1d(div_up(items, 256), stream.device().info()), {mode});
  return result;
}

// result[n] from the `count` values of image n (contiguous): mode 0 the mean
// of a, mode 1 the PSNR of a against b. Two passes: chunk sums with several
// workgroups per image, then one workgroup per image.
void per_image_reduce(Stream& stream, const Tensor& a, const Tensor& b, std::uint32_t images,
                      std::uint32_t count, std::uint32_t mode, float range_sq,
                      const Tensor& result) {
  static const KernelDef k_partial{"psnr_partial", {kT, kT, kS}, sizeof(PartialPush)};
  static const KernelDef k_finish{"psnr_finish", {kT, kS}, sizeof(FinishPush)};
  const DeviceInfo& info = stream.device().info();
  const std::uint32_t chunks = div_up(count, kChunk);
  const std::uint32_t groups = images * chunks;
  Tensor partial = Tensor::empty(stream.device(), Shape{groups});
  stream.dispatch(k_partial, {texel(a), texel(b), out(partial)}, PartialPush{groups, chunks, count},
                  groups_1d(groups, info), {mode});
  stream.dispatch(k_finish, {texel(partial), out(result)},
                  FinishPush{images, chunks, static_cast<float>(count), range_sq},
                  groups_1d(images, info), {mode});
}

}  // namespace

void psnr(Stream& stream, const Tensor& a, const Tensor& b, float data_range,
          const Tensor& out_psnr) {
  const char* op = "psnr";
  require_pair(a, b, out_psnr, op, "a", "b", "out");
  require_range(data_range, op);
  require_subgroup_arithmetic(stream, op);
  const Shape& s = a.shape();
  per_image_reduce(stream, a, b, static_cast<std::uint32_t>(s[0]),
                   static_cast<std::uint32_t>(s[1] * s[2] * s[3]), 1, data_range * data_range,
                   out_psnr);
}

void ssim(Stream& stream, const Tensor& x, const Tensor& y, float data_range,
          const Tensor& out_ssim) {
  const char* op = "ssim";
  require_pair(x, y, out_ssim, op, "x", "y", "out");
  require_range(data_range, op);
  require_subgroup_arithmetic(stream, op);
  const SsimPush p = ssim_push(x.shape(), data_range, op);
  const Horizontal t = ssim_horizontal(stream, x, y, p);
  const Tensor map = ssim_vertical(stream, t, t.t1, p, 0);
  const auto count = static_cast<std::uint32_t>(std::int64_t(p.channels) * (p.h - 10) * (p.w - 10));
  per_image_reduce(stream, map, map, static_cast<std::uint32_t>(x.shape()[0]), count, 0, 0.f,
                   out_ssim);
}

void ssim_backward(Stream& stream, const Tensor& x, const Tensor& y, float data_range,
                   const Tensor& d_ssim, const Tensor& dx) {
  static const KernelDef k_bh{"ssim_bh", {kT, kS}, sizeof(SsimPush)};
  static const KernelDef k_bv{"ssim_bv", {kT, kT, kT, kS}, sizeof(SsimPush)};
  const char* op = "ssim_backward";
  require_pair(x, y, d_ssim, op, "x", "y", "d_ssim");
  require_range(data_range, op);
  require_f32(dx, op, "dx");
  require_same_shape(x, dx, op, "x", "dx");
  const SsimPush p = ssim_push(x.shape(), data_range, op);
  const DeviceInfo& info = stream.device().info();
  const Horizontal t = ssim_horizontal(stream, x, y, p);
  const Tensor terms = ssim_vertical(stream, t, d_ssim, p, 1);
  const std::int64_t hv = p.h - 10;
  Tensor u = Tensor::empty(stream.device(), Shape{p.planes, hv, p.w, 4});
  stream.dispatch(
      k_bh, {texel(terms, kRgba), out(u)}, p,
      groups_1d(div_up(std::uint64_t(p.planes) * std::uint64_t(hv) * div_up(p.w, 4), 256), info));
  stream.dispatch(
      k_bv, {texel(u, kRgba), texel(x), texel(y), out(dx)}, p,
      groups_1d(div_up(std::uint64_t(p.planes) * div_up(p.h, 4) * std::uint64_t(p.w), 256), info));
}

}  // namespace vkjr2::kernels
