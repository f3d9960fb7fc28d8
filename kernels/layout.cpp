#include <vkjr2/kernels/check.hpp>
#include <vkjr2/kernels/fast_div.hpp>
#include <vkjr2/kernels/layout.hpp>

#include <string>

namespace vkjr2::kernels {
namespace {

// Mirrors the push block of shaders/slice.comp.
struct SlicePush {
  std::uint32_t n;
  std::int32_t ci, hi, wi, co, ho, wo;
  std::int32_t c_src0, c_dst0, cw, off_y, off_x;
  float fill;
  std::uint32_t pad_ = 0;  // uvec2 members align to 8 bytes
  Magic blocks_magic, ho_magic, cw_magic;
};
static_assert(sizeof(SlicePush) <= 128);

// Mirrors the push blocks of shaders/channel_affine.comp and
// channel_affine_grad.comp.
struct AffinePush {
  std::uint32_t hw, channels;
};
struct AffineGradPush {
  std::uint32_t batch, hw, channels;
};

// Planes of 4k floats go as vec4 (RGBA32F view, vec4 stores).
bool affine_vec4(const Shape& s) { return (s[2] * s[3]) % 4 == 0; }
// x: 1024-item chunks of a plane (floats or vec4s), y: channel, z: image.
Groups affine_groups(const Shape& s) {
  const std::int64_t items = affine_vec4(s) ? s[2] * s[3] / 4 : s[2] * s[3];
  return Groups{div_up(items, 1024), static_cast<std::uint32_t>(s[1]),
                static_cast<std::uint32_t>(s[0])};
}
void affine_dispatch(Stream& stream, const Tensor& x, const Tensor& scale, const Tensor& bias,
                     const Tensor& y, bool has_bias) {
  static const KernelDef k{
      "channel_affine",
      {BindingKind::texel, BindingKind::texel, BindingKind::texel, BindingKind::storage},
      sizeof(AffinePush)};
  const Shape& s = x.shape();
  const bool vec4 = affine_vec4(s);
  stream.dispatch(
      k,
      {texel(x, vec4 ? VK_FORMAT_R32G32B32A32_SFLOAT : VK_FORMAT_R32_SFLOAT), texel(scale),
       texel(bias), out(y)},
      AffinePush{static_cast<std::uint32_t>(s[2] * s[3]), static_cast<std::uint32_t>(s[1])},
      affine_groups(s), {has_bias ? 1u : 0u, vec4 ? 1u : 0u});
}

// Batches up to this size take whole-plane copies as transfer commands.

std::int32_t i32(std::int64_t v) { return static_cast<std::int32_t>(v); }

// Writes channels [c_dst0, c_dst0 + cw) of y from x shifted by (off_y, off_x)
// and c_src0, `fill` where the source lies outside x.
void region_copy(Stream& stream, const Tensor& x, const Tensor& y, std::int64_t c_src0,
                 std::int64_t c_dst0, std::int64_t cw, std::int64_t off_y, std::int64_t off_x,
                 float fill) {
  static const KernelDef k{"slice", {BindingKind::texel, BindingKind::storage}, sizeof(SlicePush)};
  const Shape& a = x.shape();
  const Shape& b = y.shape();
  if (off_y == 0 && off_x == 0 && a[2] == b[2] && a[3] == b[3] &&
      b[0] <= stream.device().traits().max_transfer_copies) {
    // Whole planes (concat, channel slices): one contiguous range per image,
    // moved by transfer copies (3-4× a shader copy on lavapipe; DeviceTraits).
    const std::int64_t hw = a[2] * a[3];
    for (std::int64_t n = 0; n < b[0]; ++n) {
      stream.copy(x.view(Shape{cw * hw}, (n * a[1] + c_src0) * hw),
                  y.view(Shape{cw * hw}, (n * b[1] + c_dst0) * hw));
    }
    return;
  }
  const SlicePush push{static_cast<std::uint32_t>(b[0]),
                       i32(a[1]),
                       i32(a[2]),
                       i32(a[3]),
                       i32(b[1]),
                       i32(b[2]),
                       i32(b[3]),
                       i32(c_src0),
                       i32(c_dst0),
                       i32(cw),
                       i32(off_y),
                       i32(off_x),
                       fill,
                       0,
                       magic(div_up(b[3], 4)),
                       magic(static_cast<std::uint64_t>(b[2])),
                       magic(static_cast<std::uint64_t>(cw))};
  const std::uint64_t items = std::uint64_t(b[0] * cw * b[2]) * div_up(b[3], 4);
  stream.dispatch(k, {texel(x), out(y)}, push,
                  groups_1d(div_up(items, 256), stream.device().info()));
}

void require_nchw(const Tensor& t, const char* op, const char* name) {
  require_f32_rank(t, 4, op, name);
  if (t.numel() > INT32_MAX) {
    throw InvalidArgument(
        op, std::string(name) + " " + t.shape().str() + " has more than 2^31 elements",
        "split the batch");
  }
}

std::string pad_str(const Pad2d& p) {
  return "t/b/l/r " + std::to_string(p.top) + "/" + std::to_string(p.bottom) + "/" +
         std::to_string(p.left) + "/" + std::to_string(p.right);
}

Shape padded_shape(const Shape& x, const Pad2d& p, const char* op) {
  if (p.top < 0 || p.bottom < 0 || p.left < 0 || p.right < 0) {
    throw InvalidArgument(op, "padding must be non-negative, got " + pad_str(p),
                          "crop with slice() instead");
  }
  return Shape{x[0], x[1], x[2] + p.top + p.bottom, x[3] + p.left + p.right};
}

void check_slice(const Shape& big, const Shape& small, const SliceStart& s, const char* op) {
  if (big[0] != small[0] || s.channel < 0 || s.row < 0 || s.col < 0 ||
      s.channel + small[1] > big[1] || s.row + small[2] > big[2] || s.col + small[3] > big[3]) {
    throw InvalidArgument(op, "slice " + small.str() + " at (c " + std::to_string(s.channel) +
                                  ", row " + std::to_string(s.row) + ", col " +
                                  std::to_string(s.col) + ") does not lie inside " + big.str());
  }
}

}  // namespace

void pad(Stream& stream, const Tensor& x, const Pad2d& p, float value, const Tensor& y) {
  const char* op = "pad";
  require_nchw(x, op, "x");
  require_nchw(y, op, "y");
  require_shape(y, padded_shape(x.shape(), p, op), op, "y");
  region_copy(stream, x, y, 0, 0, x.shape()[1], -p.top, -p.left, value);
}

void pad_backward(Stream& stream, const Tensor& dy, const Pad2d& p, const Tensor& dx) {
  const char* op = "pad_backward";
  require_nchw(dy, op, "dy");
  require_nchw(dx, op, "dx");
  require_shape(dy, padded_shape(dx.shape(), p, op), op, "dy");
  region_copy(stream, dy, dx, 0, 0, dx.shape()[1], p.top, p.left, 0.f);
}

void concat_channels(Stream& stream, std::span<const Tensor> xs, const Tensor& y) {
  const char* op = "concat_channels";
  if (xs.empty()) throw InvalidArgument(op, "no inputs to concatenate");
  require_nchw(y, op, "y");
  std::int64_t channels = 0;
  for (const Tensor& x : xs) {
    require_nchw(x, op, "an input");
    const Shape& s = x.shape();
    if (s[0] != y.shape()[0] || s[2] != y.shape()[2] || s[3] != y.shape()[3]) {
      throw InvalidArgument(
          op, "input " + s.str() + " and y " + y.shape().str() + " differ in N, H or W");
    }
    channels += s[1];
  }
  if (channels != y.shape()[1]) {
    throw InvalidArgument(op, "inputs have " + std::to_string(channels) + " channels in all, y " +
                                  y.shape().str() + " has " + std::to_string(y.shape()[1]));
  }
  std::int64_t offset = 0;
  for (const Tensor& x : xs) {
    region_copy(stream, x, y, 0, offset, x.shape()[1], 0, 0, 0.f);
    offset += x.shape()[1];
  }
}

void concat_channels_backward(Stream& stream, const Tensor& dy, std::span<const Tensor> dxs) {
  const char* op = "concat_channels_backward";
  if (dxs.empty()) throw InvalidArgument(op, "no gradients to split into");
  require_nchw(dy, op, "dy");
  std::int64_t channels = 0;
  for (const Tensor& dx : dxs) {
    require_nchw(dx, op, "a dx");
    const Shape& s = dx.shape();
    if (s[0] != dy.shape()[0] || s[2] != dy.shape()[2] || s[3] != dy.shape()[3]) {
      throw InvalidArgument(
          op, "dx " + s.str() + " and dy " + dy.shape().str() + " differ in N, H or W");
    }
    channels += s[1];
  }
  if (channels != dy.shape()[1]) {
    throw InvalidArgument(op, "dxs have " + std::to_string(channels) + " channels in all, dy " +
                                  dy.shape().str() + " has " + std::to_string(dy.shape()[1]));
  }
  std::int64_t offset = 0;
  for (const Tensor& dx : dxs) {
    region_copy(stream, dy, dx, offset, 0, dx.shape()[1], 0, 0, 0.f);
    offset += dx.shape()[1];
  }
}

void slice(Stream& stream, const Tensor& x, const SliceStart& s, const Tensor& y) {
  const char* op = "slice";
  require_nchw(x, op, "x");
  require_nchw(y, op, "y");
  check_slice(x.shape(), y.shape(), s, op);
  region_copy(stream, x, y, s.channel, 0, y.shape()[1], s.row, s.col, 0.f);
}

void slice_backward(Stream& stream, const Tensor& dy, const SliceStart& s, const Tensor& dx) {
  const char* op = "slice_backward";
  require_nchw(dy, op, "dy");
  require_nchw(dx, op, "dx");
  check_slice(dx.shape(), dy.shape(), s, op);
  const std::int64_t c_end = s.channel + dy.shape()[1];
  // Channels outside the slice are zero; the slice's channels get dy placed
  // at (row, col) with zeros around it.
  if (s.channel > 0 || c_end < dx.shape()[1]) stream.fill(dx, 0.f);
  region_copy(stream, dy, dx, 0, s.channel, dy.shape()[1], -s.row, -s.col, 0.f);
}

void flip_spatial(Stream& stream, const Tensor& x, const Tensor& y) {
  static const KernelDef k{
      "flip_spatial", {BindingKind::texel, BindingKind::storage}, 2 * sizeof(std::uint32_t)};
  const char* op = "flip_spatial";
  require_nchw(x, op, "x");
  require_nchw(y, op, "y");
  require_same_shape(x, y, op, "x", "y");
  const Shape& s = x.shape();
  const auto planes = std::uint64_t(s[0] * s[1]), plane = std::uint64_t(s[2] * s[3]);
  if (planes == 0 || plane == 0) return;
  if (planes > stream.device().info().max_workgroup_count[2]) {
    throw InvalidArgument(op, "x has " + std::to_string(planes) + " planes",
                          "flip at most " +
                              std::to_string(stream.device().info().max_workgroup_count[2]) +
                              " planes (N·C) per call");
  }
  Groups g = groups_1d(div_up(plane, 256), stream.device().info());
  g.z = std::uint32_t(planes);
  struct {
    std::uint32_t h, w;
  } const push{std::uint32_t(s[2]), std::uint32_t(s[3])};
  stream.dispatch(k, {texel(x), out(y)}, push, g);
}

void channel_affine(Stream& stream, const Tensor& x, const Tensor& scale, const Tensor& bias,
                    const Tensor& y) {
  const char* op = "channel_affine";
  require_f32_rank(x, 4, op, "x");
  require_f32(y, op, "y");
  require_same_shape(x, y, op, "x", "y");
  const std::int64_t c = x.shape()[1];
  if (require_f32(scale, op, "scale") != c || require_f32(bias, op, "bias") != c) {
    throw InvalidArgument(op, "scale " + scale.shape().str() + " and bias " + bias.shape().str() +
                                  " must have C = " + std::to_string(c) + " elements");
  }
  affine_dispatch(stream, x, scale, bias, y, true);
}

void channel_affine_backward(Stream& stream, const Tensor& x, const Tensor& scale, const Tensor& dy,
                             const Tensor* dx, const Tensor* dscale, const Tensor* dbias) {
  static const KernelDef k_grad{
      "channel_affine_grad",
      {BindingKind::texel, BindingKind::texel, BindingKind::storage, BindingKind::storage},
      sizeof(AffineGradPush)};
  const char* op = "channel_affine_backward";
  require_f32_rank(dy, 4, op, "dy");
  const Shape& s = dy.shape();
  const std::int64_t c = s[1];
  if (require_f32(scale, op, "scale") != c) {
    throw InvalidArgument(
        op, "scale " + scale.shape().str() + " must have C = " + std::to_string(c) + " elements");
  }
  const Device device = stream.device();
  if (dx != nullptr) {
    require_f32(*dx, op, "dx");
    require_same_shape(*dx, dy, op, "dx", "dy");
    affine_dispatch(stream, dy, scale, scale, *dx, false);
  }
  if (dscale == nullptr && dbias == nullptr) return;
  require_f32(x, op, "x");
  require_same_shape(x, dy, op, "x", "dy");
  require_subgroup_arithmetic(stream, op);
  Tensor ds = dscale != nullptr ? *dscale : Tensor::empty(device, Shape{c});
  Tensor db = dbias != nullptr ? *dbias : Tensor::empty(device, Shape{c});
  if (require_f32(ds, op, "dscale") != c || require_f32(db, op, "dbias") != c) {
    throw InvalidArgument(op, "dscale " + ds.shape().str() + " and dbias " + db.shape().str() +
                                  " must have C = " + std::to_string(c) + " elements");
  }
  stream.dispatch(
      k_grad, {texel(x), texel(dy), out(ds), out(db)},
      AffineGradPush{static_cast<std::uint32_t>(s[0]), static_cast<std::uint32_t>(s[2] * s[3]),
                     static_cast<std::uint32_t>(c)},
      groups_1d(static_cast<std::uint64_t>(c), device.info()));
}

namespace {

// Mirrors the push block of shaders/pixel_shuffle.comp.
struct ShufflePush {
  std::uint32_t h, w;
  Magic quads;  // fast_div by W/4 (the vec4 variant)
};

// small: [N, C·r², H, W]; big: [N, C, H·r, W·r]. unshuffle: big → small.
void pixel_shuffle_dispatch(Stream& stream, const char* op, bool unshuffle, const Tensor& x, int r,
                            const Tensor& y) {
  static const KernelDef k{
      "pixel_shuffle", {BindingKind::texel, BindingKind::storage}, sizeof(ShufflePush)};
  const Tensor& small = unshuffle ? y : x;
  const Tensor& big = unshuffle ? x : y;
  const char* small_name = unshuffle ? "y" : "x";
  const char* big_name = unshuffle ? "x" : "y";
  require_f32_rank(small, 4, op, small_name);
  require_f32_rank(big, 4, op, big_name);
  if (r < 1 || r > 16) {
    throw InvalidArgument(op, "factor r = " + std::to_string(r), "use a factor in [1, 16]");
  }
  const Shape& s = small.shape();
  const std::int64_t rr = std::int64_t(r) * r;
  if (s[1] % rr != 0) {
    throw InvalidArgument(op,
                          std::string(small_name) + " " + s.str() + " has " + std::to_string(s[1]) +
                              " channels, not a multiple of r² = " + std::to_string(rr),
                          "give it C·r² channels");
  }
  require_shape(big, Shape{s[0], s[1] / rr, s[2] * r, s[3] * r}, op, big_name);
  const Shape& b = big.shape();
  const DeviceInfo& info = stream.device().info();
  if (b[2] > info.max_workgroup_count[1] || b[0] * b[1] > info.max_workgroup_count[2]) {
    throw InvalidArgument(
        op, std::string(big_name) + " " + b.str() + " needs more workgroups than the device allows",
        "split the batch or the channels into smaller tensors");
  }
  const auto h = static_cast<std::uint32_t>(s[2]), w = static_cast<std::uint32_t>(s[3]);
  const auto planes = static_cast<std::uint32_t>(b[0] * b[1]);
  // Quads of small pixels in all phases (shaders/pixel_shuffle.comp, VEC4).
  constexpr std::uint32_t lanes = 64;
  const std::uint64_t quads = std::uint64_t(h) * (w / 4);
  const bool vec4 = w % 4 == 0 && r <= 4 && x.vk_offset() % 16 == 0 && y.vk_offset() % 16 == 0 &&
                    div_up(quads, lanes) <= info.max_workgroup_count[0];
  if (vec4) {
    stream.dispatch(k, {texel(x, VK_FORMAT_R32G32B32A32_SFLOAT), out(y)},
                    ShufflePush{h, w, magic(w / 4)},
                    Groups{static_cast<std::uint32_t>(div_up(quads, lanes)), 1, planes},
                    {static_cast<std::uint32_t>(r), unshuffle ? 1u : 0u, 1u, lanes});
    return;
  }
  stream.dispatch(
      k, {texel(x), out(y)}, ShufflePush{h, w, {}},
      Groups{div_up(std::uint64_t(b[3]), 256), static_cast<std::uint32_t>(b[2]), planes},
      {static_cast<std::uint32_t>(r), unshuffle ? 1u : 0u, 0u, 256u});
}

}  // namespace

void pixel_shuffle(Stream& stream, const Tensor& x, int r, const Tensor& y) {
  pixel_shuffle_dispatch(stream, "pixel_shuffle", false, x, r, y);
}

void pixel_unshuffle(Stream& stream, const Tensor& x, int r, const Tensor& y) {
  pixel_shuffle_dispatch(stream, "pixel_unshuffle", true, x, r, y);
}

}  // namespace vkjr2::kernels
