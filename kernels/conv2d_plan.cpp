#include <vkjr2/kernels/check.hpp>
#include <vkjr2/kernels/conv2d.hpp>

#include <algorithm>
#include <string>

#include "internal/conv2d_impl.hpp"

namespace vkjr2::kernels {
namespace detail {

std::string str(std::int64_t v) { return std::to_string(v); }

void check_params(const char* op, const Conv2dParams& p) {
  if (p.stride_y < 1 || p.stride_x < 1) {
    throw InvalidArgument(op,
                          "stride (" + str(p.stride_y) + ", " + str(p.stride_x) + ") must be >= 1");
  }
  if (p.dilation_y < 1 || p.dilation_x < 1) {
    throw InvalidArgument(
        op, "dilation (" + str(p.dilation_y) + ", " + str(p.dilation_x) + ") must be >= 1");
  }
  if (p.pad.top < 0 || p.pad.bottom < 0 || p.pad.left < 0 || p.pad.right < 0) {
    throw InvalidArgument(op, "padding (top " + str(p.pad.top) + ", bottom " + str(p.pad.bottom) +
                                  ", left " + str(p.pad.left) + ", right " + str(p.pad.right) +
                                  ") must be >= 0");
  }
  if (p.groups < 1) throw InvalidArgument(op, "groups " + str(p.groups) + " must be >= 1");
}

// Validates x [N, Cin, H, W] and weight [Cout, Cin/groups, KH, KW] against p.
Dims dims_of(const char* op, const Shape& x, const Shape& w, const Conv2dParams& p) {
  check_params(op, p);
  if (x.rank() != 4) {
    throw InvalidArgument(op, "x " + x.str() + " must be 4-D [N, Cin, H, W]");
  }
  if (w.rank() != 4) {
    throw InvalidArgument(op, "weight " + w.str() + " must be 4-D [Cout, Cin/groups, KH, KW]",
                          "repack HWIO (TF) weights to OIHW");
  }
  if (x.numel() == 0 || w.numel() == 0) {
    throw InvalidArgument(op, "x " + x.str() + " or weight " + w.str() + " is empty",
                          "skip the op for empty inputs");
  }
  Dims d{x[0], x[1], x[2], x[3], w[0], w[2], w[3], 0, 0};
  if (d.cin % p.groups != 0 || d.cout % p.groups != 0) {
    throw InvalidArgument(op, "groups " + str(p.groups) + " must divide Cin " + str(d.cin) +
                                  " and Cout " + str(d.cout));
  }
  if (w[1] != d.cin / p.groups) {
    throw InvalidArgument(op, "weight " + w.str() + " has " + str(w[1]) +
                                  " input channels, expected Cin/groups = " +
                                  str(d.cin / p.groups) + " (x " + x.str() + ")");
  }
  const std::int64_t span_y = (d.kh - 1) * p.dilation_y + 1;
  const std::int64_t span_x = (d.kw - 1) * p.dilation_x + 1;
  const std::int64_t in_y = d.h + p.pad.top + p.pad.bottom;
  const std::int64_t in_x = d.w + p.pad.left + p.pad.right;
  if (span_y > in_y || span_x > in_x) {
    throw InvalidArgument(op,
                          "kernel extent " + str(span_y) + "×" + str(span_x) +
                              " exceeds the padded input " + str(in_y) + "×" + str(in_x),
                          "pad the input or use a smaller kernel");
  }
  d.hout = (in_y - span_y) / p.stride_y + 1;
  d.wout = (in_x - span_x) / p.stride_x + 1;
  return d;
}

ConvPush push_of(const Dims& d, const Conv2dParams& p) {
  ConvPush c{};
  c.n = std::uint32_t(d.n);
  c.cin = std::uint32_t(d.cin);
  c.h = std::uint32_t(d.h);
  c.w = std::uint32_t(d.w);
  c.cout = std::uint32_t(d.cout);
  c.hout = std::uint32_t(d.hout);
  c.wout = std::uint32_t(d.wout);
  c.kh = std::uint32_t(d.kh);
  c.kw = std::uint32_t(d.kw);
  c.sy = std::uint32_t(p.stride_y);
  c.sx = std::uint32_t(p.stride_x);
  c.dy = std::uint32_t(p.dilation_y);
  c.dx = std::uint32_t(p.dilation_x);
  c.pt = p.pad.top;
  c.pl = p.pad.left;
  c.groups = std::uint32_t(p.groups);
  c.act = std::uint32_t(p.activation);
  c.slope = p.leaky_slope;
  c.cin_g = std::uint32_t(d.cin / p.groups);
  c.cout_g = std::uint32_t(d.cout / p.groups);
  c.yh = c.hout;
  c.yw = c.wout;
  c.xrelu = p.relu_input ? 1u : 0u;
  return c;
}

// The one choice of tile for these shapes (the padded input's geometry
// depends on it, so producers and consumers of a padded tensor call it on the
// same ConvPush). Measured on lavapipe (recognition-net shapes, CPU time per
// conv): a weight fetch (the same texel in every lane) costs about twice an
// input fetch, and the accumulators live on the stack either way, so the
// best tiles are large (up to ~25 vec4) with no wasted pixels:
//  - a row of at most DeviceTraits::conv_max_row_tile pixels is one block (px = wout: a 10-wide
//    row in 8-pixel blocks wastes 6 of 16 pixels);
//  - stride 1: 4 channels × ry rows (half the weight fetches per FMA of 8
//    channels × 1 row), ry splitting the rows evenly;
//  - strided: 8 channels × 1 row when that fits, else 4 channels.
BlockedTile blocked_tile(const ConvPush& c, const DeviceTraits& tr) {
  BlockedTile t;
  const std::uint32_t max_row_tile = tr.conv_max_row_tile;
  const std::uint32_t max_accumulators = tr.conv_max_tile_accumulators;
  if (c.wout <= max_row_tile) {
    t.px = c.wout;
  } else {  // the fewest computed pixels per row, then the widest block
    std::uint32_t best = ~0u;
    // Strided: at most half the accumulators (12 on lavapipe), so that 8
    // channels fit (their input rows are long).
    const std::uint32_t max_px = c.sx == 1 ? max_row_tile : max_accumulators / 2;
    for (std::uint32_t px = max_px; px >= 4; --px) {
      if (px * c.sx % 4 != 0) continue;  // every block's row segment starts 4-aligned
      const std::uint32_t slots = div_up(c.wout, px) * px;
      if (slots < best) {
        best = slots;
        t.px = px;
      }
    }
  }
  if (c.sy == 1 && c.dy == 1) {
    t.cg = 1;
    const std::uint32_t ry_max = std::max(1u, max_accumulators / t.px);
    t.ry = div_up(c.hout, div_up(c.hout, ry_max));
  } else {
    t.cg = 2 * t.px <= max_accumulators ? 2 : 1;
  }
  return t;
}

void set_padded(ConvPush& c, std::uint32_t px, std::uint32_t ry, std::uint32_t sh) {
  c.wblocks = (c.wout + px - 1) / px;
  c.hp = (div_up(c.hout, ry) * ry - 1) * c.sy + (c.kh - 1) * c.dy + 1;
  // wp rounded up to 4: rows start 16-byte aligned, read as vec4 texels.
  c.wp = div_up((c.wblocks * px - 1) * c.sx + (c.kw - 1) * c.dx + 1 + sh, 4) * 4;
}

void set_padded(ConvPush& c, const BlockedTile& t) { set_padded(c, t.px, t.ry, t.sh); }

// The depthwise kernel's tile: one channel × ry rows × px pixels (px · ry
// float accumulators). A row of up to DeviceTraits::depthwise_max_row_tile pixels is one block;
// wider rows take the 8..16-pixel block that computes the fewest pixels
// (strided: 8). Stride 1 stacks rows up to depthwise_max_accumulators, split evenly:
// the KH − 1 input rows the outputs share are read once, and the 9 weights
// once per px · ry outputs (on lavapipe the weight fetches, the same address
// in every lane, cost as much as the FMAs).
BlockedTile depthwise_tile(const ConvPush& c, const DeviceTraits& tr) {
  BlockedTile t;
  const std::uint32_t max_row_tile = tr.depthwise_max_row_tile;
  const std::uint32_t max_accumulators = tr.depthwise_max_accumulators;
  t.cg = 1;
  t.sh = (4u - std::uint32_t(c.pl) % 4u) % 4u;
  if (c.wout <= max_row_tile) {
    t.px = c.wout;
  } else if (c.sx == 1) {
    std::uint32_t best = ~0u;
    for (std::uint32_t px = max_row_tile; px >= 8; px -= 4) {
      const std::uint32_t slots = div_up(c.wout, px) * px;
      if (slots < best) {
        best = slots;
        t.px = px;
      }
    }
  } else {
    t.px = 8;
  }
  if (c.sy == 1 && c.dy == 1) {
    const std::uint32_t ry_max = std::clamp(max_accumulators / t.px, 1u, 4u);
    t.ry = div_up(c.hout, div_up(c.hout, ry_max));
  }
  return t;
}

BlockedTile padded_tile(const ConvPush& c, Conv2dAlgo algo, const DeviceTraits& tr) {
  return algo == Conv2dAlgo::depthwise ? depthwise_tile(c, tr) : blocked_tile(c, tr);
}

std::uint64_t padded_elements(const Dims& d, const Conv2dParams& p, Conv2dAlgo algo,
                              const DeviceTraits& tr) {
  ConvPush c = push_of(d, p);
  set_padded(c, padded_tile(c, algo, tr));
  return std::uint64_t(d.n) * std::uint64_t(d.cin) * c.hp * c.wp;
}

PlaneLayout padded_layout(const Dims& d, const Conv2dParams& p, Conv2dAlgo algo,
                          const DeviceTraits& tr) {
  ConvPush c = push_of(d, p);
  const BlockedTile t = padded_tile(c, algo, tr);
  set_padded(c, t);
  return PlaneLayout{c.hp, c.wp, p.pad.top, p.pad.left + std::int32_t(t.sh)};
}

void refuse_relu_input(const char* op, const Conv2dParams& p) {
  if (p.relu_input) {
    throw InvalidArgument(op, "relu_input is forward only",
                          "apply the ReLU as its own op where a gradient is needed");
  }
}

bool small_kernel(const Dims& d, const Conv2dParams& p) {
  return d.kh <= kMaxBlockedTaps && d.kw <= kMaxBlockedTaps && p.stride_x <= kMaxBlockedStep &&
         p.dilation_x <= kMaxBlockedStep;
}

std::string why_not(Conv2dAlgo algo, const Device& device, const Dims& d, const Conv2dParams& p) {
  const DeviceInfo& info = device.info();
  const DeviceTraits& tr = device.traits();
  const std::uint64_t texel_limit =
      std::min<std::uint64_t>(info.max_texel_buffer_elements, std::uint64_t(1) << 31);
  switch (algo) {
    case Conv2dAlgo::auto_select:
    case Conv2dAlgo::direct:
      return {};
    case Conv2dAlgo::blocked:
      if (p.groups != 1) return "needs groups == 1";
      if (p.relu_input) return "takes no input ReLU";
      if (!small_kernel(d, p)) return "needs KH, KW <= 7 and stride_x, dilation_x <= 4";
      if (padded_elements(d, p, algo, tr) > texel_limit) {
        return "the padded input exceeds the texel limit";
      }
      return {};
    case Conv2dAlgo::pointwise:
      if (p.relu_input) return "takes no input ReLU";
      if (p.groups != 1 || d.kh != 1 || d.kw != 1 || p.stride_y != 1 || p.stride_x != 1 ||
          p.pad.top != 0 || p.pad.bottom != 0 || p.pad.left != 0 || p.pad.right != 0) {
        return "needs a 1×1 kernel, stride 1, no padding and groups == 1";
      }
      return {};
    case Conv2dAlgo::depthwise:
      if (p.groups != d.cin || d.cout % d.cin != 0) return "needs groups == Cin";
      if (!small_kernel(d, p)) return "needs KH, KW <= 7 and stride_x, dilation_x <= 4";
      if (padded_elements(d, p, algo, tr) > texel_limit) {
        return "the padded input exceeds the texel limit";
      }
      return {};
  }
  return "unknown variant";
}

Conv2dAlgo select(const Device& device, const Dims& d, const Conv2dParams& p, const char* op) {
  if (p.algo != Conv2dAlgo::auto_select) {
    const std::string why = why_not(p.algo, device, d, p);
    if (!why.empty()) {
      throw InvalidArgument(op,
                            std::string("variant ") + conv2d_algo_name(p.algo) +
                                " cannot run this convolution: " + why,
                            "use Conv2dAlgo::auto_select");
    }
    return p.algo;
  }
  // The one selection point. On every device so far the register-blocked
  // kernels win (LAVAPIPE.md); a GPU-specific shared-memory variant would be
  // chosen here from info.type.
  for (Conv2dAlgo a : {Conv2dAlgo::pointwise, Conv2dAlgo::depthwise, Conv2dAlgo::blocked}) {
    if (why_not(a, device, d, p).empty()) return a;
  }
  return Conv2dAlgo::direct;
}

}  // namespace detail

const char* conv2d_algo_name(Conv2dAlgo algo) noexcept {
  switch (algo) {
    case Conv2dAlgo::auto_select:
      return "auto_select";
    case Conv2dAlgo::direct:
      return "direct";
    case Conv2dAlgo::blocked:
      return "blocked";
    case Conv2dAlgo::pointwise:
      return "pointwise";
    case Conv2dAlgo::depthwise:
      return "depthwise";
  }
  return "?";
}

Padding2d same_padding(std::int64_t in_h, std::int64_t in_w, int kh, int kw, int stride_y,
                       int stride_x, int dilation_y, int dilation_x) {
  if (in_h < 1 || in_w < 1 || kh < 1 || kw < 1 || stride_y < 1 || stride_x < 1 || dilation_y < 1 ||
      dilation_x < 1) {
    throw InvalidArgument("same_padding", "sizes, kernel, stride and dilation must be >= 1");
  }
  auto axis = [](std::int64_t in, int k, int s, int d, int& before, int& after) {
    const std::int64_t out = (in + s - 1) / s;
    const std::int64_t total = std::max<std::int64_t>((out - 1) * s + (k - 1) * d + 1 - in, 0);
    before = int(total / 2);
    after = int(total - total / 2);
  };
  Padding2d pad;
  axis(in_h, kh, stride_y, dilation_y, pad.top, pad.bottom);
  axis(in_w, kw, stride_x, dilation_x, pad.left, pad.right);
  return pad;
}

Shape conv2d_output_shape(const Shape& x, const Shape& weight, const Conv2dParams& p) {
  const detail::Dims d = detail::dims_of("conv2d_output_shape", x, weight, p);
  return Shape{d.n, d.cout, d.hout, d.wout};
}

Conv2dPlan::Conv2dPlan(const Device& device, const Shape& x, const Shape& weight,
                       const Conv2dParams& p)
    : x_(x), weight_(weight), p_(p) {
  const char* op = "Conv2dPlan";
  const detail::Dims d = detail::dims_of(op, x, weight, p);
  y_ = Shape{d.n, d.cout, d.hout, d.wout};
  algo_ = detail::select(device, d, p, op);
  if (algo_ == Conv2dAlgo::blocked || algo_ == Conv2dAlgo::depthwise) {
    input_layout_ = detail::padded_layout(d, p, algo_, device.traits());
  }
  device_ = device.shared_core().get();
}

bool Conv2dPlan::writes_padded() const noexcept {
  return algo_ == Conv2dAlgo::blocked || algo_ == Conv2dAlgo::depthwise ||
         algo_ == Conv2dAlgo::pointwise;
}

bool Conv2dPlan::reads_packed_weight() const noexcept {
  return algo_ == Conv2dAlgo::blocked || algo_ == Conv2dAlgo::pointwise;
}

std::string Conv2dPlan::residual_misfit(const Planes& r) const {
  using detail::str;
  const std::string want =
      "[" + str(y_[0]) + ", 1.." + str(y_[1]) + ", " + str(y_[2]) + ", " + str(y_[3]) + "]";
  const Shape& rs = r.shape;
  if (!r.defined() || rs.rank() != 4 || rs[0] != y_[0] || rs[1] < 1 || rs[1] > y_[1] ||
      rs[2] != y_[2] || rs[3] != y_[3]) {
    return "residual " + (r.defined() ? rs.str() : std::string("(undefined)")) +
           " must be [N, C, Hout, Wout] = " + want;
  }
  const std::int64_t planes = rs[0] * rs[1];
  if (!r.padded()) {
    if (!(r.data.shape() == rs)) return "the plain residual's data is not " + rs.str();
    return {};
  }
  std::string misfit = layout_misfit(rs, r.layout);
  if (!misfit.empty()) return misfit;
  if (r.data.numel() != planes * std::int64_t(r.layout.hp) * std::int64_t(r.layout.wp)) {
    return "the padded residual's data " + r.data.shape().str() + " is not " + str(planes) +
           " planes of " + r.layout.str();
  }
  if (algo_ == Conv2dAlgo::pointwise) return {};
  if (algo_ == Conv2dAlgo::blocked) {
    if (y_[2] != x_[2] || y_[3] != x_[3] || !(r.layout == input_layout_)) {
      return "a padded residual of the blocked variant must be in its input layout (" +
             input_layout_.str() + ", got " + r.layout.str() + ") with y of x's size";
    }
    return {};
  }
  return std::string("the ") + conv2d_algo_name(algo_) + " variant reads plain residuals only";
}

void Conv2dPlan::pack(Stream& stream, const Tensor& weight) {
  const char* op = "Conv2dPlan::pack";
  if (!defined()) throw InvalidArgument(op, "the plan is empty", "make it for the convolution");
  require_f32(weight, op, "weight");
  require_shape(weight, weight_, op, "weight");
  if (!reads_packed_weight()) return;
  detail::ConvPush c{};
  c.cout = std::uint32_t(weight_[0]);
  c.cin = std::uint32_t(weight_[1]);
  c.kh = std::uint32_t(weight_[2]);
  c.kw = std::uint32_t(weight_[3]);
  packed_ = detail::pack_weights(stream, weight, c, false);
}

}  // namespace vkjr2::kernels
