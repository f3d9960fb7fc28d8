#include <vkjr2/kernels/check.hpp>
#include <vkjr2/kernels/fast_div.hpp>
#include <vkjr2/kernels/flow.hpp>
#include <vkjr2/kernels/pool.hpp>
#include <vkjr2/kernels/warp.hpp>

#include <cmath>
#include <string>

namespace vkjr2::kernels {
namespace {

constexpr std::uint32_t kGroup = 256;  // flow_lk_*.comp: one pixel per invocation

// Mirrors the push block of shaders/flow_lk_terms.comp.
struct TermsPush {
  std::uint32_t n;
  std::int32_t h, w;
  std::uint32_t ref_per_image;
  std::uint32_t plane_m, plane_l, row_m, row_l;
};
// Mirrors the push block of shaders/flow_lk_solve.comp.
struct SolvePush {
  std::uint32_t n, plane;
  float min_eigenvalue;
  std::uint32_t pad0;
  std::uint32_t plane_m, plane_l;
};

}  // namespace

void lucas_kanade_step(Stream& stream, const Tensor& ref, const Tensor& img, const Tensor& flow_in,
                       const Tensor& flow_out, const Tensor& min_eig, const LucasKanade& p) {
  static const KernelDef k_terms{
      "flow_lk_terms",
      {BindingKind::texel, BindingKind::texel, BindingKind::texel, BindingKind::storage},
      sizeof(TermsPush)};
  static const KernelDef k_solve{
      "flow_lk_solve",
      {BindingKind::texel, BindingKind::texel, BindingKind::storage, BindingKind::storage},
      sizeof(SolvePush)};
  const char* op = "lucas_kanade_step";
  require_f32_rank(img, 4, op, "img");
  require_f32_rank(ref, 4, op, "ref");
  const Shape& s = img.shape();
  if (s[1] != 1) throw InvalidArgument(op, "img " + s.str() + " must have one channel (N×1×H×W)");
  const Shape& rs = ref.shape();
  if (rs[1] != 1 || rs[2] != s[2] || rs[3] != s[3] || (rs[0] != 1 && rs[0] != s[0])) {
    throw InvalidArgument(op, "ref " + rs.str() + " must be 1×1×H×W or N×1×H×W for img " + s.str());
  }
  require_f32_rank(flow_in, 4, op, "flow_in");
  require_shape(flow_in, Shape{s[0], 2, s[2], s[3]}, op, "flow_in");
  require_f32(flow_out, op, "flow_out");
  require_shape(flow_out, Shape{s[0], 2, s[2], s[3]}, op, "flow_out");
  if (flow_out.vk_buffer() == flow_in.vk_buffer() && flow_out.vk_offset() == flow_in.vk_offset()) {
    throw InvalidArgument(op, "flow_out must not be flow_in (pass another tensor)");
  }
  if (min_eig.defined()) {
    require_f32(min_eig, op, "min_eig");
    require_shape(min_eig, Shape{s[0], 1, s[2], s[3]}, op, "min_eig");
  }
  if (p.radius < 0 || p.radius > 64) {
    throw InvalidArgument(op, "radius " + std::to_string(p.radius) + " must be in [0, 64]");
  }
  if (!(p.min_eigenvalue > 0.f) || !std::isfinite(p.min_eigenvalue)) {
    throw InvalidArgument(op, "min_eigenvalue " + std::to_string(p.min_eigenvalue) +
                                  " must be a positive finite number");
  }
  const Device& dev = stream.device();
  const DeviceInfo& info = dev.info();
  const std::uint64_t plane = std::uint64_t(s[2]) * std::uint64_t(s[3]);
  const std::uint64_t pixels = std::uint64_t(s[0]) * plane;
  if (5 * pixels >= (std::uint64_t(1) << 31)) {
    throw InvalidArgument(op, "img " + s.str() + " is too large (5·N·H·W must stay below 2^31)");
  }
  const Groups groups = groups_1d(div_up(pixels, kGroup), info);

  const Tensor warped = Tensor::empty(dev, s);
  warp(stream, img, flow_in, warped, SamplePadding::border);

  const Tensor terms = Tensor::empty(dev, Shape{s[0], 5, s[2], s[3]});
  const Magic pm = magic(plane), rm = magic(std::uint64_t(s[3]));
  stream.dispatch(
      k_terms, {texel(ref), texel(warped), texel(flow_in), out(terms)},
      TermsPush{static_cast<std::uint32_t>(s[0]), static_cast<std::int32_t>(s[2]),
                static_cast<std::int32_t>(s[3]), rs[0] == 1 ? 0u : 1u, pm.m, pm.l, rm.m, rm.l},
      groups);

  // Window means: a box mean of 2r + 1 taps applied twice along each axis
  // (only the taps inside the image counted; the same divisors for the five
  // planes of a pixel, so S⁻¹ b does not depend on them).
  const std::int32_t k = 2 * p.radius + 1;
  const Pool2d along_x{1, k, 1, 1, 0, 0, p.radius, p.radius};
  const Pool2d along_y{k, 1, 1, 1, p.radius, p.radius, 0, 0};
  const Tensor a = Tensor::empty(dev, terms.shape());
  const Tensor sums = Tensor::empty(dev, terms.shape());
  avg_pool2d(stream, terms, along_x, false, a);
  avg_pool2d(stream, a, along_x, false, sums);
  avg_pool2d(stream, sums, along_y, false, a);
  avg_pool2d(stream, a, along_y, false, sums);

  const Tensor eig = min_eig.defined() ? min_eig : Tensor::empty(dev, Shape{s[0], 1, s[2], s[3]});
  stream.dispatch(k_solve, {texel(sums), texel(flow_in), out(flow_out), out(eig)},
                  SolvePush{static_cast<std::uint32_t>(s[0]), static_cast<std::uint32_t>(plane),
                            p.min_eigenvalue, 0u, pm.m, pm.l},
                  groups);
}

}  // namespace vkjr2::kernels
