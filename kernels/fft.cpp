#include <vkjr2/kernels/check.hpp>
#include <vkjr2/kernels/fft.hpp>

#include <algorithm>
#include <array>
#include <cmath>
#include <numbers>
#include <string>

namespace vkjr2::kernels {
namespace {

constexpr std::uint32_t kLocalSize = 64;  // fft_common.glsl local_size_x
constexpr std::uint32_t kPadWhenDivisibleBy = 8;
// The largest radix of one pass, as log2, where no device chooses
// (fft_supported_length); plans use DeviceTraits::fft_max_log2_radix.
constexpr std::uint32_t kMaxLog2Radix = 5;  // radix 32

// Mirrors the push-constant block of shaders/fft_common.glsl.
struct FftPassPush {
  std::uint32_t count;
  std::uint32_t n;
  std::uint32_t nr;
  std::uint32_t p;
  std::uint32_t tw_step;
  std::uint32_t inner;
  std::array<std::uint32_t, 2> div_inner;
  std::array<std::uint32_t, 2> div_nr;
  std::array<std::uint32_t, 2> div_p;
  std::uint32_t in_stride;
  std::uint32_t in_outer;
  std::uint32_t out_stride;
  std::uint32_t out_outer;
  std::uint32_t in_len;
  std::uint32_t out_len;
  std::uint32_t out_real;
  float in_im_sign;
  std::array<float, 2> out_scale;
};
static_assert(sizeof(FftPassPush) <= 128);
static_assert(sizeof(FftPassPush) == 88);

const KernelDef& pass_kernel(std::uint32_t radix) {
  using B = BindingKind;
  static const std::vector<B> bindings{B::texel, B::texel, B::storage};
  static const KernelDef k1{"fft_r1", bindings, sizeof(FftPassPush)};
  static const KernelDef k2{"fft_r2", bindings, sizeof(FftPassPush)};
  static const KernelDef k3{"fft_r3", bindings, sizeof(FftPassPush)};
  static const KernelDef k4{"fft_r4", bindings, sizeof(FftPassPush)};
  static const KernelDef k5{"fft_r5", bindings, sizeof(FftPassPush)};
  static const KernelDef k7{"fft_r7", bindings, sizeof(FftPassPush)};
  static const KernelDef k8{"fft_r8", bindings, sizeof(FftPassPush)};
  static const KernelDef k16{"fft_r16", bindings, sizeof(FftPassPush)};
  static const KernelDef k32{"fft_r32", bindings, sizeof(FftPassPush)};
  switch (radix) {
    case 1:
      return k1;
    case 2:
      return k2;
    case 3:
      return k3;
    case 4:
      return k4;
    case 5:
      return k5;
    case 7:
      return k7;
    case 8:
      return k8;
    case 16:
      return k16;
    case 32:
      return k32;
    default:
      throw Error("fft", "no shader for radix " + std::to_string(radix), "report a bug");
  }
}

// Magic number for fast_div32() in fft_common.glsl: exact unsigned division of
// any 32-bit numerator by d (Granlund & Montgomery 1994, Fig. 4.1).
std::array<std::uint32_t, 2> div_magic(std::uint32_t d) {
  std::uint32_t l = 0;
  while ((std::uint64_t{1} << l) < d) ++l;
  const std::uint64_t m = ((std::uint64_t{1} << 32) * ((std::uint64_t{1} << l) - d)) / d + 1;
  const std::uint32_t sh1 = std::min(l, 1u), sh2 = l > 0 ? l - 1 : 0;
  return {static_cast<std::uint32_t>(m), sh1 | (sh2 << 8)};
}

// Radices for length n: the power of two in as few passes of ≤ 32 as
// possible, split evenly (1024 → 32·32, 512 → 32·16, 128 → 16·8), then 3s,
// 5s, 7s. Fewer passes won on lavapipe: 1024² c2c fell from 3+3 to 2+2 passes
// and about 1.5× in time (the largest radix is a device trait).
// Empty when n has another prime factor (or n == 1).
bool radices_for(std::uint32_t n, std::vector<std::uint32_t>& radices,
                 std::uint32_t max_log2_radix = kMaxLog2Radix) {
  radices.clear();
  std::uint32_t twos = 0;
  while (n % 2 == 0) {
    n /= 2;
    ++twos;
  }
  if (twos > 0) {
    const std::uint32_t passes = (twos + max_log2_radix - 1) / max_log2_radix;
    for (std::uint32_t i = 0; i < passes; ++i) {
      radices.push_back(1u << (twos / passes + (i < twos % passes ? 1 : 0)));
    }
  }
  for (std::uint32_t f : {3u, 5u, 7u}) {
    while (n % f == 0) {
      n /= f;
      radices.push_back(f);
    }
  }
  return n == 1;
}

Tensor twiddle_table(const Device& device, std::uint32_t n) {
  std::vector<float> w(2 * std::size_t(n));
  for (std::uint32_t t = 0; t < n; ++t) {
    const double angle = -2.0 * std::numbers::pi * double(t) / double(n);
    w[2 * t] = static_cast<float>(std::cos(angle));
    w[2 * t + 1] = static_cast<float>(std::sin(angle));
  }
  return Tensor::from(device, Shape{std::int64_t(n), 2}, w);
}

std::uint32_t checked_axis(std::int64_t n, const char* axis, std::vector<std::uint32_t>& radices,
                           std::uint32_t max_log2_radix) {
  const std::string name(axis);
  if (n < 1) {
    throw InvalidArgument("FftPlan", name + " must be >= 1, got " + std::to_string(n));
  }
  if (n > (std::int64_t{1} << 24) ||
      !radices_for(static_cast<std::uint32_t>(n), radices, max_log2_radix)) {
    throw InvalidArgument(
        "FftPlan",
        name + " " + std::to_string(n) +
            " is not a supported FFT length (a product of 2, 3, 5 and 7, "
            "at most 2^24)",
        "pad the " + name + " to " + std::to_string(fft_next_length(n)) + " (fft_next_length)");
  }
  return static_cast<std::uint32_t>(n);
}

// One dispatch: a radix pass over one axis of every transform in the batch.
struct Pass {
  std::uint32_t radix = 1, n = 1, p = 1;
  std::uint32_t inner = 1, outer = 1;  // transforms: outer groups of `inner` interleaved ones
  std::uint32_t in_stride = 1, in_outer = 1, out_stride = 1, out_outer = 1;
  std::uint32_t in_len = 1, out_len = 1;
  bool real_in = false, real_out = false;
  float in_im_sign = 1.f;
  std::array<float, 2> out_scale{1.f, 1.f};
  const Tensor* twiddles = nullptr;
  std::uint64_t out_floats() const { return std::uint64_t(outer) * out_outer * (real_out ? 1 : 2); }
};

// Passes of one axis over a contiguous layout: element i of transform
// (o, c) at o · outer_stride + i · stride + c.
void add_axis(std::vector<Pass>& passes, const std::vector<std::uint32_t>& radices, std::uint32_t n,
              std::uint32_t inner, std::uint32_t outer, std::uint32_t stride,
              std::uint32_t outer_stride, const Tensor* twiddles) {
  std::uint32_t p = 1;
  for (std::uint32_t r : radices) {
    Pass s;
    s.radix = r;
    s.n = n;
    s.p = p;
    s.inner = inner;
    s.outer = outer;
    s.in_stride = s.out_stride = stride;
    s.in_outer = s.out_outer = outer_stride;
    s.in_len = s.out_len = n;
    s.twiddles = twiddles;
    passes.push_back(s);
    p *= r;
  }
}

bool overlaps(const Tensor& a, const Tensor& b) {
  if (a.vk_buffer() != b.vk_buffer()) return false;
  const VkDeviceSize a0 = a.vk_offset(), b0 = b.vk_offset();
  return a0 < b0 + b.bytes() && b0 < a0 + a.bytes();
}

}  // namespace

bool fft_supported_length(std::int64_t n) {
  if (n < 1 || n > (std::int64_t{1} << 24)) return false;
  std::vector<std::uint32_t> radices;
  return radices_for(static_cast<std::uint32_t>(n), radices);
}

std::int64_t fft_next_length(std::int64_t n) {
  std::int64_t m = std::max<std::int64_t>(n, 1);
  while (true) {
    std::int64_t r = m;
    for (std::int64_t f : {2, 3, 5, 7}) {
      while (r % f == 0) r /= f;
    }
    if (r == 1) return m;
    ++m;
  }
}

FftPlan::FftPlan(const Device& device, const Shape& shape, FftKind kind, FftNorm norm)
    : device_(device), kind_(kind), norm_(norm) {
  if (shape.rank() != 2 && shape.rank() != 3) {
    throw InvalidArgument("FftPlan", "shape must be {B, H, W} or {H, W}, got " + shape.str());
  }
  const bool batched = shape.rank() == 3;
  if (batched && shape[0] < 1) {
    throw InvalidArgument("FftPlan", "batch must be >= 1, got " + shape.str());
  }
  batch_ = batched ? static_cast<std::uint32_t>(std::min<std::int64_t>(shape[0], 1 << 30)) : 1;
  const std::uint32_t max_log2_radix = std::clamp(device.traits().fft_max_log2_radix, 1u, 5u);
  height_ = checked_axis(shape[-2], "height", column_radices_, max_log2_radix);
  width_ = checked_axis(shape[-1], "width", row_radices_, max_log2_radix);
  const std::uint64_t floats = 2ull * batch_ * height_ * width_;
  if (floats >= (1ull << 31) || (batched && shape[0] >= (1 << 30))) {
    throw InvalidArgument("FftPlan",
                          "shape " + shape.str() + " is too large (" + std::to_string(floats) +
                              " floats, limit 2^31)",
                          "split the batch into several calls");
  }
  const std::int64_t h = height_, w = width_, half = width_ / 2 + 1;
  auto with_batch = [&](std::initializer_list<std::int64_t> dims) {
    std::vector<std::int64_t> d;
    if (batched) d.push_back(batch_);
    d.insert(d.end(), dims);
    return Shape(std::span<const std::int64_t>(d));
  };
  if (kind == FftKind::c2c) {
    signal_shape_ = spectrum_shape_ = with_batch({h, w, 2});
  } else {
    signal_shape_ = with_batch({h, w});
    spectrum_shape_ = with_batch({h, half, 2});
  }
  if (width_ > 1) row_twiddles_ = twiddle_table(device, width_);
  if (height_ > 1) {
    column_twiddles_ = height_ == width_ ? row_twiddles_ : twiddle_table(device, height_);
  }
}

void FftPlan::forward(Stream& stream, const Tensor& in, const Tensor& out) const {
  const char* op = "FftPlan::forward";
  require_f32(in, op, "in");
  require_f32(out, op, "out");
  require_shape(in, signal_shape_, op, "in");
  require_shape(out, spectrum_shape_, op, "out");
  run(stream, in, out, false);
}

void FftPlan::inverse(Stream& stream, const Tensor& in, const Tensor& out) const {
  const char* op = "FftPlan::inverse";
  require_f32(in, op, "in");
  require_f32(out, op, "out");
  require_shape(in, spectrum_shape_, op, "in");
  require_shape(out, signal_shape_, op, "out");
  run(stream, in, out, true);
}

void FftPlan::run(Stream& stream, const Tensor& in, const Tensor& out, bool inverse) const {
  const bool real = kind_ == FftKind::r2c;
  const std::uint32_t b = batch_, h = height_, w = width_;
  const std::uint32_t half = real ? w / 2 + 1 : w;  // columns of the spectrum

  // Rows (W axis) see the full width; columns (H axis) the spectrum's width.
  // r2c: rows, then columns; c2r: columns, then rows; c2c: rows, then columns.
  std::vector<Pass> passes;
  // Between the axes the data sits in rows of `pitch` elements: padded by one
  // when a power-of-two row length would put every element a column pass
  // reads (rows nr apart) into the same cache set.
  const bool both_axes = !row_radices_.empty() && !column_radices_.empty();
  const std::uint32_t pitch = both_axes && half % kPadWhenDivisibleBy == 0 ? half + 1 : half;
  auto add_rows = [&] {
    const std::size_t first = passes.size();
    add_axis(passes, row_radices_, w, 1, b * h, 1, w, &row_twiddles_);
    if (passes.size() == first) return;
    if (!inverse || !real) {
      passes.back().out_outer = column_radices_.empty() ? half : pitch;
      passes.back().out_len = half;  // r2c: keep the half spectrum
    }
    if (real && inverse) {
      passes[first].in_outer = column_radices_.empty() ? half : pitch;
      passes[first].in_len = half;  // read the half spectrum, mirror the rest
    }
  };
  auto add_columns = [&] {
    const std::size_t first = passes.size();
    add_axis(passes, column_radices_, h, half, b, pitch, h * pitch, &column_twiddles_);
    if (passes.size() == first) return;
    if (real && inverse) {  // columns first: read the caller's layout
      passes[first].in_stride = half;
      passes[first].in_outer = h * half;
    } else {  // columns last: write the caller's layout
      passes.back().out_stride = half;
      passes.back().out_outer = h * half;
    }
  };
  if (real && inverse) {
    add_columns();
    add_rows();
  } else {
    add_rows();
    add_columns();
  }
  if (passes.empty()) add_axis(passes, {1}, 1, 1, b * h * w, 1, 1, nullptr);  // 1×1: identity

  const double n = double(h) * double(w);
  double scale = 1.0;
  if (norm_ == FftNorm::ortho) scale = 1.0 / std::sqrt(n);
  if (norm_ == FftNorm::backward && inverse) scale = 1.0 / n;
  // inverse = conj(F(conj(x))): conjugate on the first load and the last store.
  passes.front().in_im_sign = inverse ? -1.f : 1.f;
  passes.front().real_in = real && !inverse;
  passes.back().out_scale = {float(scale), float(inverse ? -scale : scale)};
  passes.back().real_out = real && inverse;

  const Device device = stream.device();
  std::uint64_t temp_floats = 0;
  for (std::size_t i = 0; i + 1 < passes.size(); ++i) {
    temp_floats = std::max(temp_floats, passes[i].out_floats());
  }
  // A single pass cannot run in place (Stockham): route it through a temporary.
  const bool staged = passes.size() == 1 && overlaps(in, out);
  if (staged) temp_floats = std::max(temp_floats, passes[0].out_floats());
  std::array<Tensor, 2> temps;
  const std::size_t n_temps = std::min<std::size_t>(passes.size() - 1 + (staged ? 1 : 0), 2);
  for (std::size_t i = 0; i < n_temps; ++i) {
    temps[i] = Tensor::empty(device, Shape{std::int64_t(temp_floats)});
  }

  Tensor src = in;
  for (std::size_t i = 0; i < passes.size(); ++i) {
    const Pass& s = passes[i];
    const bool last = i + 1 == passes.size() && !staged;
    const Tensor dst = last ? out : temps[i % 2].view(Shape{std::int64_t(s.out_floats())});
    const std::uint32_t nr = s.n / s.radix;
    const std::uint64_t count = std::uint64_t(s.outer) * nr * s.inner;
    FftPassPush push{};
    push.count = static_cast<std::uint32_t>(count);
    push.n = s.n;
    push.nr = nr;
    push.p = s.p;
    push.tw_step = s.n / (s.p * s.radix);
    push.inner = s.inner;
    push.div_inner = div_magic(s.inner);
    push.div_nr = div_magic(nr);
    push.div_p = div_magic(s.p);
    push.in_stride = s.in_stride;
    push.in_outer = s.in_outer;
    push.out_stride = s.out_stride;
    push.out_outer = s.out_outer;
    push.in_len = s.in_len;
    push.out_len = s.out_len;
    push.out_real = s.real_out ? 1 : 0;
    push.in_im_sign = s.in_im_sign;
    push.out_scale = s.out_scale;
    // Passes without twiddles (p == 1) still bind a table: any one will do.
    const Tensor& tw = s.twiddles && s.twiddles->defined() ? *s.twiddles
                       : row_twiddles_.defined()           ? row_twiddles_
                       : column_twiddles_.defined()        ? column_twiddles_
                                                           : src;
    const VkFormat src_format = s.real_in ? VK_FORMAT_R32_SFLOAT : VK_FORMAT_R32G32_SFLOAT;
    const VkFormat tw_format =
        &tw == &src && s.real_in ? VK_FORMAT_R32_SFLOAT : VK_FORMAT_R32G32_SFLOAT;
    stream.dispatch(pass_kernel(s.radix),
                    {texel(src, src_format), texel(tw, tw_format), vkjr2::out(dst)}, push,
                    groups_1d(div_up(count, kLocalSize), device.info()));
    src = dst;
  }
  if (staged) stream.copy(src, out);
}

void fft2_host(const Device& device, const Shape& shape, std::vector<float>& data, bool inverse,
               FftNorm norm) {
  if (shape.rank() != 3)
    throw InvalidArgument("fft2_host", "shape must be {B, H, W}, got " + shape.str());
  const Tensor t = Tensor::from(device, Shape{shape[0], shape[1], shape[2], 2}, data);
  const FftPlan plan(device, shape, FftKind::c2c, norm);
  Stream stream(device);
  if (inverse) {
    plan.inverse(stream, t, t);
  } else {
    plan.forward(stream, t, t);
  }
  stream.run();
  t.download(data);
}

void fft2(Stream& stream, const Tensor& in, const Tensor& out, bool inverse, FftNorm norm) {
  const Shape& s = in.shape();
  if (!in.defined() || (s.rank() != 3 && s.rank() != 4) || s[-1] != 2) {
    throw InvalidArgument("fft2", "in must be complex [B, H, W, 2] or [H, W, 2], got " +
                                      (in.defined() ? s.str() : std::string("undefined")));
  }
  const Shape plan_shape = s.rank() == 4 ? Shape{s[0], s[1], s[2]} : Shape{s[0], s[1]};
  const FftPlan plan(stream.device(), plan_shape, FftKind::c2c, norm);
  if (inverse) {
    plan.inverse(stream, in, out);
  } else {
    plan.forward(stream, in, out);
  }
}

}  // namespace vkjr2::kernels
