#include <vkjr2/kernels/check.hpp>
#include <vkjr2/kernels/psf_conv.hpp>

#include <string>

namespace vkjr2::kernels {
namespace {

struct PsfPush {
  std::int32_t n, k, h, w;
};
static_assert(sizeof(PsfPush) <= 128);

constexpr std::uint32_t kLocalX = 16, kLocalY = 8;

struct Dims {
  std::int64_t n, c, k, h, w, s;
};

Dims check_inputs(const Tensor& x, const Tensor& beta, const Tensor& psi, const char* op) {
  require_f32_rank(x, 4, op, "x");
  require_f32_rank(beta, 4, op, "beta");
  require_f32_rank(psi, 3, op, "psi");
  const Shape& xs = x.shape();
  const Shape& bs = beta.shape();
  const Shape& ps = psi.shape();
  const Dims d{xs[0], xs[1], bs[1], xs[2], xs[3], ps[1]};
  if (d.c < 1 || d.c > 4) {
    throw InvalidArgument(
        op, "x " + xs.str() + " has " + std::to_string(d.c) + " channels; 1 to 4 are supported",
        "split the channels into groups of at most 4");
  }
  if (bs[0] != d.n || bs[2] != d.h || bs[3] != d.w) {
    throw InvalidArgument(
        op, "beta " + bs.str() + " does not match x " + xs.str() + " (expected [N, K, H, W])");
  }
  if (ps[0] != d.k || ps[1] != ps[2] || ps[1] % 2 == 0) {
    throw InvalidArgument(op, "psi " + ps.str() + " must be [K, S, S] with K = " +
                                  std::to_string(d.k) + " (beta's channels) and S odd");
  }
  if (d.s > 65) {
    throw InvalidArgument(op, "kernel size " + std::to_string(d.s) + " exceeds 65");
  }
  return d;
}

Groups grid(const Dims& d) {
  return {div_up(std::uint64_t(d.w), kLocalX), div_up(std::uint64_t(d.h), kLocalY),
          static_cast<std::uint32_t>(d.n)};
}

}  // namespace

void psf_conv(Stream& stream, const Tensor& x, const Tensor& beta, const Tensor& psi,
              const Tensor& y, const Tensor& norm, PsfConvParams params) {
  static const KernelDef kFwd{"psf_conv",
                              {BindingKind::texel, BindingKind::texel, BindingKind::texel,
                               BindingKind::storage, BindingKind::storage},
                              sizeof(PsfPush)};
  const Dims d = check_inputs(x, beta, psi, "psf_conv");
  require_f32(y, "psf_conv", "y");
  require_shape(y, x.shape(), "psf_conv", "y");
  require_f32(norm, "psf_conv", "norm");
  require_shape(norm, Shape{d.n, 1, d.h, d.w}, "psf_conv", "norm");
  stream.dispatch(
      kFwd, {texel(x), texel(beta), texel(psi), out(y), out(norm)},
      PsfPush{std::int32_t(d.n), std::int32_t(d.k), std::int32_t(d.h), std::int32_t(d.w)}, grid(d),
      {std::uint32_t(d.s), std::uint32_t(d.c), params.normalize ? 1u : 0u});
}

void psf_conv_backward(Stream& stream, const Tensor& x, const Tensor& beta, const Tensor& psi,
                       const Tensor& y, const Tensor& norm, const Tensor& dy, const Tensor& dx,
                       const Tensor& dbeta, PsfConvParams params) {
  static const KernelDef kBwd{
      "psf_conv_backward",
      {BindingKind::texel, BindingKind::texel, BindingKind::texel, BindingKind::texel,
       BindingKind::texel, BindingKind::texel, BindingKind::storage, BindingKind::storage},
      sizeof(PsfPush)};
  const char* op = "psf_conv_backward";
  const Dims d = check_inputs(x, beta, psi, op);
  require_f32(dy, op, "dy");
  require_shape(dy, x.shape(), op, "dy");
  require_f32(dx, op, "dx");
  require_shape(dx, x.shape(), op, "dx");
  require_f32(dbeta, op, "dbeta");
  require_shape(dbeta, beta.shape(), op, "dbeta");
  if (params.normalize) {
    require_f32(y, op, "y");
    require_shape(y, x.shape(), op, "y");
    require_f32(norm, op, "norm");
    require_shape(norm, Shape{d.n, 1, d.h, d.w}, op, "norm");
  }
  // The plain form reads neither y nor norm; bind dy in their place.
  const Tensor& y_arg = params.normalize ? y : dy;
  const Tensor& norm_arg = params.normalize ? norm : dy;
  stream.dispatch(
      kBwd,
      {texel(x), texel(beta), texel(psi), texel(dy), texel(y_arg), texel(norm_arg), out(dx),
       out(dbeta)},
      PsfPush{std::int32_t(d.n), std::int32_t(d.k), std::int32_t(d.h), std::int32_t(d.w)}, grid(d),
      {std::uint32_t(d.s), std::uint32_t(d.c), params.normalize ? 1u : 0u});
}

}  // namespace vkjr2::kernels
