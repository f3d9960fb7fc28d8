#include <vkjr2/kernels/check.hpp>
#include <vkjr2/kernels/psf_conv.hpp>

#include <algorithm>
#include <cmath>
#include <span>
#include <string>
#include <vector>

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

namespace {

struct PackPush {
  std::int32_t n, k, h, w, hp, wp, k0, kc;
};
struct MacPush {
  std::int32_t bins, kc, planes, k0, accumulate;
};
struct FinishPush {
  std::int32_t n, h, w, hp, wp;
};
static_assert(sizeof(PackPush) <= 128 && sizeof(MacPush) <= 128 && sizeof(FinishPush) <= 128);

}  // namespace

PsfConvFft::~PsfConvFft() = default;

PsfConvFft::PsfConvFft(const Device& device, const Tensor& psi, std::int64_t batch,
                       std::int64_t channels, std::int64_t height, std::int64_t width,
                       std::int64_t max_temporary_bytes)
    : device_(device), n_(batch), c_(channels), h_(height), w_(width) {
  if (max_temporary_bytes == 0) max_temporary_bytes = device.traits().psf_fft_max_temporary_bytes;
  const char* op = "PsfConvFft";
  require_f32_rank(psi, 3, op, "psi");
  k_ = psi.shape()[0];
  s_ = psi.shape()[1];
  if (psi.shape()[2] != s_ || s_ % 2 == 0 || k_ < 1) {
    throw InvalidArgument(op, "psi " + psi.shape().str() + " must be [K, S, S] with S odd");
  }
  if (n_ < 1 || c_ < 1 || c_ > 4 || h_ < 1 || w_ < 1) {
    throw InvalidArgument(op, "images must be [N >= 1, 1..4 channels, H >= 1, W >= 1]");
  }
  hp_ = fft_next_length(h_ + s_ - 1);
  wp_ = fft_next_length(w_ + s_ - 1);
  const std::int64_t bins = hp_ * (wp_ / 2 + 1);
  // The FFT's own scratch is a full complex plane per image (hp·wp·2 floats).
  const std::int64_t per_kernel = n_ * (c_ + 1) * std::max(bins, hp_ * wp_) * 2 * 4;
  chunk_ = std::clamp<std::int64_t>(max_temporary_bytes / per_kernel, 1, k_);
  if (per_kernel > max_temporary_bytes) {
    throw InvalidArgument(op,
                          "images " + std::to_string(n_) + "x" + std::to_string(c_) + "x" +
                              std::to_string(h_) + "x" + std::to_string(w_) +
                              " are too large for the FFT path's temporaries",
                          "use the direct path or fewer images per batch");
  }
  // ψ_k circularly centred at (0, 0) on the padded grid, then r2c.
  const std::vector<float> p = psi.download();
  const std::int64_t r = s_ / 2;
  std::vector<float> padded(std::size_t(k_ * hp_ * wp_), 0.f);
  for (std::int64_t k = 0; k < k_; ++k)
    for (std::int64_t i = 0; i < s_; ++i)
      for (std::int64_t j = 0; j < s_; ++j) {
        const std::int64_t y = (i - r + hp_) % hp_, x = (j - r + wp_) % wp_;
        padded[std::size_t((k * hp_ + y) * wp_ + x)] = p[std::size_t((k * s_ + i) * s_ + j)];
      }
  // In chunks of kernels, as the transforms below (the FFT's scratch is a
  // full complex plane per image); assembled on the host, as chunk offsets
  // need not meet the device's view alignment.
  const std::int64_t spectrum = hp_ * (wp_ / 2 + 1) * 2;
  std::vector<float> hat(std::size_t(k_ * spectrum));
  const std::int64_t psi_chunk =
      std::clamp<std::int64_t>(max_temporary_bytes / (hp_ * wp_ * 2 * 4), 1, k_);
  for (std::int64_t k0 = 0; k0 < k_; k0 += psi_chunk) {
    const std::int64_t kc = std::min(psi_chunk, k_ - k0);
    const Tensor part = Tensor::from(device_, {kc, hp_, wp_},
                                     std::span<const float>(padded).subspan(
                                         std::size_t(k0 * hp_ * wp_), std::size_t(kc * hp_ * wp_)));
    const Tensor part_hat = Tensor::empty(device_, {kc, hp_, wp_ / 2 + 1, 2});
    const FftPlan plan(device_, {kc, hp_, wp_}, FftKind::r2c, FftNorm::none);
    Stream stream(device_);
    plan.forward(stream, part, part_hat);
    stream.run();
    part_hat.download(
        std::span<float>(hat).subspan(std::size_t(k0 * spectrum), std::size_t(kc * spectrum)));
  }
  psi_hat_ = Tensor::from(device_, {k_, hp_, wp_ / 2 + 1, 2}, hat);
  forward_ = std::make_unique<FftPlan>(device_, Shape{n_ * chunk_ * (c_ + 1), hp_, wp_},
                                       FftKind::r2c, FftNorm::none);
  if (const std::int64_t last = k_ % chunk_; last != 0) {
    forward_last_ = std::make_unique<FftPlan>(device_, Shape{n_ * last * (c_ + 1), hp_, wp_},
                                              FftKind::r2c, FftNorm::none);
  }
  inverse_ = std::make_unique<FftPlan>(device_, Shape{n_ * (c_ + 1), hp_, wp_}, FftKind::r2c,
                                       FftNorm::backward);
}

void PsfConvFft::forward(Stream& stream, const Tensor& x, const Tensor& beta, const Tensor& y,
                         const Tensor& norm, PsfConvParams params) const {
  static const KernelDef kPack{"psf_fft_pack",
                               {BindingKind::texel, BindingKind::texel, BindingKind::storage},
                               sizeof(PackPush)};
  static const KernelDef kMac{"psf_fft_mac",
                              {BindingKind::texel, BindingKind::texel, BindingKind::storage},
                              sizeof(MacPush)};
  static const KernelDef kFinish{"psf_fft_finish",
                                 {BindingKind::texel, BindingKind::storage, BindingKind::storage},
                                 sizeof(FinishPush)};
  const char* op = "PsfConvFft::forward";
  require_shape(x, Shape{n_, c_, h_, w_}, op, "x");
  require_shape(beta, Shape{n_, k_, h_, w_}, op, "beta");
  require_shape(y, Shape{n_, c_, h_, w_}, op, "y");
  require_shape(norm, Shape{n_, 1, h_, w_}, op, "norm");
  const std::int64_t planes = c_ + 1, half = wp_ / 2 + 1, bins = hp_ * half;
  const Tensor acc = Tensor::empty(device_, {n_ * planes, hp_, half, 2});
  // One pair of temporaries serves every chunk (the last one uses their start).
  const Tensor u_all = Tensor::empty(device_, {n_ * chunk_ * planes, hp_, wp_});
  const Tensor u_hat_all = Tensor::empty(device_, {n_ * chunk_ * planes, hp_, half, 2});
  for (std::int64_t k0 = 0; k0 < k_; k0 += chunk_) {
    const std::int64_t kc = std::min(chunk_, k_ - k0);
    if (k0 > 0) {
      // Release the previous chunk's FFT scratch before the next is taken:
      // large images would otherwise hold every chunk's at once.
      stream.run();
    }
    const Tensor u = kc == chunk_ ? u_all : u_all.view(Shape{n_ * kc * planes, hp_, wp_});
    const Tensor u_hat =
        kc == chunk_ ? u_hat_all : u_hat_all.view(Shape{n_ * kc * planes, hp_, half, 2});
    stream.dispatch(
        kPack, {texel(x), texel(beta), out(u)},
        PackPush{std::int32_t(n_), std::int32_t(k_), std::int32_t(h_), std::int32_t(w_),
                 std::int32_t(hp_), std::int32_t(wp_), std::int32_t(k0), std::int32_t(kc)},
        Groups{div_up(std::uint64_t(wp_), 16), div_up(std::uint64_t(hp_), 8),
               std::uint32_t(n_ * kc)},
        {std::uint32_t(c_)});
    (kc == chunk_ ? *forward_ : *forward_last_).forward(stream, u, u_hat);
    stream.dispatch(kMac,
                    {texel(psi_hat_, VK_FORMAT_R32G32_SFLOAT),
                     texel(u_hat, VK_FORMAT_R32G32_SFLOAT), k0 == 0 ? out(acc) : inout(acc)},
                    MacPush{std::int32_t(bins), std::int32_t(kc), std::int32_t(planes),
                            std::int32_t(k0), k0 == 0 ? 0 : 1},
                    Groups{div_up(std::uint64_t(bins), 64), std::uint32_t(n_ * planes), 1});
  }
  const Tensor r = Tensor::empty(device_, {n_ * planes, hp_, wp_});
  inverse_->inverse(stream, acc, r);
  stream.dispatch(
      kFinish, {texel(r), out(y), out(norm)},
      FinishPush{std::int32_t(n_), std::int32_t(h_), std::int32_t(w_), std::int32_t(hp_),
                 std::int32_t(wp_)},
      Groups{div_up(std::uint64_t(w_), 16), div_up(std::uint64_t(h_), 8), std::uint32_t(n_)},
      {std::uint32_t(c_), params.normalize ? 1u : 0u});
}

PsfConvPath psf_conv_path(const DeviceTraits& traits, std::int64_t n, std::int64_t c,
                          std::int64_t k, std::int64_t s, std::int64_t h, std::int64_t w) {
  const double hp = double(fft_next_length(h + s - 1)), wp = double(fft_next_length(w + s - 1));
  // Seconds per unit (DeviceTraits: measured on lavapipe by the kernels_bench psf rows).
  const double direct = double(n * h * w) * double(k * s * s) * traits.psf_direct_seconds_per_tap;
  const double fft =
      double(n * k * (c + 1)) * hp * wp * std::log2(hp * wp) * traits.psf_fft_seconds_per_point_log;
  const double bytes = double(n * (c + 1)) * hp * wp * 8;  // one kernel's FFT scratch
  return fft < direct && bytes <= double(traits.psf_fft_max_temporary_bytes) ? PsfConvPath::fft
                                                                             : PsfConvPath::direct;
}

}  // namespace vkjr2::kernels
