#include <vkjr2/kernels/check.hpp>
#include <vkjr2/kernels/warp.hpp>

#include <string>

#include "internal/sample.hpp"

namespace vkjr2::kernels {
namespace {

constexpr std::uint32_t kSampleGroup = 128;  // warp_sample*.comp: one pixel per invocation
constexpr std::uint32_t kPackGroup = 256;    // warp_pack_rgba: 256 invocations in x
constexpr std::uint32_t kRgbaTileX = 128, kRgbaTileY = 1;  // warp_sample_rgba workgroup
constexpr std::uint32_t kAbsMaxPerGroup = 4096;            // warp_absmax: 256 invocations × 16
constexpr std::uint32_t kToFloatPerGroup = 1024;           // warp_fixed_to_float: 256 × 4

// Mirrors the push block of shaders/warp_sampling.glsl.
struct SamplePush {
  std::uint32_t n_batch, channels, in_h, in_w, out_h, out_w;
  std::uint32_t padding;  // 0 zeros, 1 border
  std::uint32_t align_corners;
  std::uint32_t count_log2;
};
static_assert(sizeof(SamplePush) <= 128);

struct AbsMaxPush {
  std::uint32_t n;
};

// Mirrors the push block of shaders/warp_pack_rgba.comp.
struct PackPush {
  std::uint32_t n_batch, channels, plane, groups;
};
static_assert(sizeof(PackPush) <= 128);

SamplePush make_push(const detail::SampleGeometry& g) {
  std::uint32_t log2 = 0;
  const std::uint64_t plane_out = std::uint64_t(g.out_h) * g.out_w;
  while ((std::uint64_t(1) << log2) < plane_out) ++log2;
  return {g.n_batch,
          g.channels,
          g.in_h,
          g.in_w,
          g.out_h,
          g.out_w,
          g.padding == SamplePadding::border ? 1u : 0u,
          g.align_corners ? 1u : 0u,
          log2};
}

// The one place the forward sampler is chosen. RGBA: pack the image into
// RGBA texels first (one pass) so that each bilinear tap is one texel read
// for four channels; worth it from 3 channels when the output is not much
// smaller than the input (warp: same size; a small grid_sample crop of a
// large image would pay the pack for pixels it never reads).
bool use_rgba_sampler(const detail::SampleGeometry& g, const DeviceInfo& info) {
  const std::uint64_t plane_in = std::uint64_t(g.in_h) * g.in_w;
  const std::uint64_t plane_out = std::uint64_t(g.out_h) * g.out_w;
  const std::uint64_t groups = div_up(g.channels, 4);
  const std::uint64_t texels = std::uint64_t(g.n_batch) * groups * plane_in;
  const auto& max_groups = info.max_workgroup_count;
  return g.channels >= 3 && plane_in <= 2 * plane_out && texels <= info.max_texel_buffer_elements &&
         16 * texels <= info.max_storage_buffer_range &&
         div_up(plane_in, kPackGroup) <= max_groups[0] && g.n_batch * groups <= max_groups[1] &&
         div_up(g.out_w, kRgbaTileX) <= max_groups[0] &&
         div_up(g.out_h, kRgbaTileY) <= max_groups[1] && g.n_batch <= max_groups[2];
}

VkFormat coords_format(const detail::SampleGeometry& g) {
  return g.grid_mode ? VK_FORMAT_R32G32_SFLOAT : VK_FORMAT_R32_SFLOAT;
}

Groups pixel_groups(const detail::SampleGeometry& g, const Stream& stream) {
  const std::uint64_t pixels = std::uint64_t(g.n_batch) * g.out_h * g.out_w;
  return groups_1d(div_up(pixels, kSampleGroup), stream.device().info());
}

// Image, flow and output shapes of warp; returns the geometry.
detail::SampleGeometry warp_geometry(const Tensor& img, const Tensor& flow, SamplePadding padding,
                                     const char* op) {
  require_f32_rank(img, 4, op, "img");
  require_f32_rank(flow, 4, op, "flow");
  const Shape& s = img.shape();
  require_shape(flow, Shape{s[0], 2, s[2], s[3]}, op, "flow");
  detail::SampleGeometry g;
  g.n_batch = static_cast<std::uint32_t>(s[0]);
  g.channels = static_cast<std::uint32_t>(s[1]);
  g.in_h = g.out_h = static_cast<std::uint32_t>(s[2]);
  g.in_w = g.out_w = static_cast<std::uint32_t>(s[3]);
  g.padding = padding;
  return g;
}

}  // namespace

namespace detail {

void sample_forward(Stream& stream, const SampleGeometry& g, const Tensor& img,
                    const Tensor& coords, const Tensor& out) {
  static const KernelDef kSample{"warp_sample",
                                 {BindingKind::texel, BindingKind::texel, BindingKind::storage},
                                 sizeof(SamplePush)};
  static const KernelDef kPack{
      "warp_pack_rgba", {BindingKind::texel, BindingKind::storage}, sizeof(PackPush)};
  static const KernelDef kSampleRgba{"warp_sample_rgba",
                                     {BindingKind::texel, BindingKind::texel, BindingKind::storage},
                                     sizeof(SamplePush)};
  const DeviceInfo& info = stream.device().info();
  if (!use_rgba_sampler(g, info)) {
    stream.dispatch(kSample, {texel(img), texel(coords, coords_format(g)), vkjr2::out(out)},
                    make_push(g), pixel_groups(g, stream), {g.grid_mode ? 1u : 0u});
    return;
  }
  const std::uint32_t groups = div_up(g.channels, 4);
  const std::uint32_t plane = g.in_h * g.in_w;
  const std::uint64_t texels = std::uint64_t(g.n_batch) * groups * plane;
  const Tensor packed =
      Tensor::empty(stream.device(), Shape{std::int64_t(texels), 4});  // N×G×H×W×4
  // Four pixels per invocation where every channel plane starts on a 16-byte boundary.
  const bool quads = plane % 4 == 0 && img.vk_offset() % 16 == 0;
  stream.dispatch(kPack,
                  {texel(img, quads ? VK_FORMAT_R32G32B32A32_SFLOAT : VK_FORMAT_R32_SFLOAT),
                   vkjr2::out(packed)},
                  PackPush{g.n_batch, g.channels, plane, groups},
                  Groups{div_up(quads ? plane / 4 : plane, kPackGroup), g.n_batch * groups, 1},
                  {quads ? 1u : 0u});
  stream.dispatch(kSampleRgba,
                  {texel(packed, VK_FORMAT_R32G32B32A32_SFLOAT), texel(coords, coords_format(g)),
                   vkjr2::out(out)},
                  make_push(g),
                  Groups{div_up(g.out_w, kRgbaTileX), div_up(g.out_h, kRgbaTileY), g.n_batch},
                  {g.grid_mode ? 1u : 0u});
}

void sample_backward(Stream& stream, const SampleGeometry& g, const Tensor& img,
                     const Tensor& coords, const Tensor& d_out, const Tensor* d_img,
                     const Tensor* d_coords) {
  static const KernelDef kAbsMax{
      "warp_absmax", {BindingKind::texel, BindingKind::storage}, sizeof(AbsMaxPush)};
  static const KernelDef kBackward{
      "warp_sample_backward",
      {BindingKind::texel, BindingKind::texel, BindingKind::texel, BindingKind::storage,
       BindingKind::storage, BindingKind::storage},
      sizeof(SamplePush)};
  static const KernelDef kToFloat{
      "warp_fixed_to_float",
      {BindingKind::storage, BindingKind::storage, BindingKind::storage},
      sizeof(SamplePush)};
  const Device device = stream.device();
  const SamplePush push = make_push(g);
  // Unused bindings get a one-element placeholder (the shader's specialization
  // constants compile their accesses out).
  Tensor max_abs = Tensor::empty(device, Shape{1}, DType::u32);
  Tensor acc = max_abs;
  Tensor coords_grad = d_coords ? *d_coords : Tensor::empty(device, Shape{1});
  if (d_img) {
    const std::uint32_t n_out = static_cast<std::uint32_t>(d_out.numel());
    stream.fill(max_abs, 0u);
    stream.dispatch(kAbsMax, {texel(d_out), inout(max_abs)}, AbsMaxPush{n_out},
                    groups_1d(div_up(n_out, kAbsMaxPerGroup), device.info()));
    acc = Tensor::empty(device, Shape{2 * d_img->numel()}, DType::u32);
    stream.fill(acc, 0u);
  }
  stream.dispatch(kBackward,
                  {texel(img), texel(coords, coords_format(g)), texel(d_out), in(max_abs),
                   inout(acc), vkjr2::out(coords_grad)},
                  push, pixel_groups(g, stream),
                  {g.grid_mode ? 1u : 0u, d_img ? 1u : 0u, d_coords ? 1u : 0u});
  if (d_img) {
    stream.dispatch(kToFloat, {in(max_abs), in(acc), vkjr2::out(*d_img)}, push,
                    groups_1d(div_up(d_img->numel(), kToFloatPerGroup), device.info()));
  }
}

}  // namespace detail

void warp(Stream& stream, const Tensor& img, const Tensor& flow, const Tensor& out,
          SamplePadding padding) {
  const detail::SampleGeometry g = warp_geometry(img, flow, padding, "warp");
  require_f32(out, "warp", "out");
  require_same_shape(img, out, "warp", "img", "out");
  detail::sample_forward(stream, g, img, flow, out);
}

void warp_backward(Stream& stream, const Tensor& img, const Tensor& flow, const Tensor& d_out,
                   const Tensor* d_img, const Tensor* d_flow, SamplePadding padding) {
  const char* op = "warp_backward";
  const detail::SampleGeometry g = warp_geometry(img, flow, padding, op);
  require_f32(d_out, op, "d_out");
  require_same_shape(img, d_out, op, "img", "d_out");
  if (!d_img && !d_flow) {
    throw InvalidArgument(op, "both d_img and d_flow are null", "pass at least one of them");
  }
  if (d_img) {
    require_f32(*d_img, op, "d_img");
    require_same_shape(img, *d_img, op, "img", "d_img");
    if (d_img->numel() >= (std::int64_t(1) << 31)) {
      throw InvalidArgument(op, "d_img " + d_img->shape().str() + " has 2^31 or more elements",
                            "split the batch");
    }
  }
  if (d_flow) {
    require_f32(*d_flow, op, "d_flow");
    require_same_shape(flow, *d_flow, op, "flow", "d_flow");
  }
  detail::sample_backward(stream, g, img, flow, d_out, d_img, d_flow);
}

}  // namespace vkjr2::kernels
