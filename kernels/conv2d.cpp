#include <vkjr2/kernels/check.hpp>
#include <vkjr2/kernels/conv2d.hpp>

#include <algorithm>
#include <string>

namespace vkjr2::kernels {
namespace {

// Mirrors the push-constant block in shaders/conv2d_common.glsl.
struct ConvPush {
  std::uint32_t n, cin, h, w;
  std::uint32_t cout, hout, wout, kh;
  std::uint32_t kw, sy, sx, dy;
  std::uint32_t dx;
  std::int32_t pt, pl;
  std::uint32_t groups;
  std::uint32_t act;
  float slope;
  std::uint32_t has_bias;
  std::uint32_t hp, wp;
  std::uint32_t wblocks;
  std::uint32_t cin_g, cout_g;
  std::uint32_t has_res;
  std::uint32_t cres;
  std::uint32_t yh, yw;
  std::uint32_t ytop, yleft;
  std::uint32_t xrelu;
};
static_assert(sizeof(ConvPush) == 31 * 4 && sizeof(ConvPush) <= 128);

constexpr std::uint32_t kPx = 8;  // output pixels per invocation (blocked, pointwise, depthwise)
constexpr std::uint32_t kCoBlock = 8;  // output channels per invocation (blocked, pointwise)
constexpr std::uint32_t kBlockedGroup = 64;
constexpr int kMaxBlockedTaps = 7;        // KH, KW ≤ 7 unroll in the blocked/depthwise kernels
constexpr int kMaxBlockedStep = 4;        // stride_x, dilation_x ≤ 4
constexpr std::uint32_t kPadGroups = 32;  // conv2d_pad: workgroups to aim for

const KernelDef kDirect{"conv2d_direct",
                        {BindingKind::texel, BindingKind::texel, BindingKind::texel,
                         BindingKind::storage, BindingKind::texel},
                        sizeof(ConvPush)};
const KernelDef kBlocked{"conv2d_blocked",
                         {BindingKind::texel, BindingKind::texel, BindingKind::texel,
                          BindingKind::storage, BindingKind::texel},
                         sizeof(ConvPush)};
const KernelDef kPointwise{"conv2d_pointwise",
                           {BindingKind::texel, BindingKind::texel, BindingKind::texel,
                            BindingKind::storage, BindingKind::texel},
                           sizeof(ConvPush)};
const KernelDef kDepthwise{"conv2d_depthwise",
                           {BindingKind::texel, BindingKind::texel, BindingKind::texel,
                            BindingKind::storage, BindingKind::texel},
                           sizeof(ConvPush)};
const KernelDef kPad{"conv2d_pad", {BindingKind::texel, BindingKind::storage}, sizeof(ConvPush)};
const KernelDef kPack{"conv2d_pack", {BindingKind::texel, BindingKind::storage}, sizeof(ConvPush)};
const KernelDef kBwdData{"conv2d_bwd_data",
                         {BindingKind::texel, BindingKind::texel, BindingKind::storage},
                         sizeof(ConvPush)};
const KernelDef kBwdWeight{"conv2d_bwd_weight",
                           {BindingKind::texel, BindingKind::texel, BindingKind::storage},
                           sizeof(ConvPush)};
const KernelDef kBwdWeightBlocked{"conv2d_bwd_weight_blocked",
                                  {BindingKind::texel, BindingKind::texel, BindingKind::storage},
                                  sizeof(ConvPush)};
const KernelDef kBwdBias{
    "conv2d_bwd_bias", {BindingKind::texel, BindingKind::storage}, sizeof(ConvPush)};

struct Dims {
  std::int64_t n, cin, h, w, cout, kh, kw, hout, wout;
};

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

// The blocked kernel's tile: each invocation computes 4·cg output channels ×
// ry rows × px consecutive pixels (cg·ry·px vec4 accumulators).
struct BlockedTile {
  std::uint32_t px = kPx, cg = 2, ry = 1;
  // Depthwise: extra zero columns left of the padding, so that the interior
  // (the producer's output) starts at a multiple of 4 and the pointwise conv
  // before it stores whole vec4 quads (the padded tensor's left = pad left + sh).
  std::uint32_t sh = 0;
};

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

// Padded-input geometry for the blocked and depthwise kernels: every row read
// by a block of px × ry output pixels lies inside [hp, wp].
// sh: zero columns before the left padding (BlockedTile::sh).
void set_padded(ConvPush& c, std::uint32_t px = kPx, std::uint32_t ry = 1, std::uint32_t sh = 0) {
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

// The tile of the variants that read a padded input (blocked, depthwise).
BlockedTile padded_tile(const ConvPush& c, Conv2dAlgo algo, const DeviceTraits& tr) {
  return algo == Conv2dAlgo::depthwise ? depthwise_tile(c, tr) : blocked_tile(c, tr);
}

// Elements of the padded input the blocked or depthwise kernel (its tile's
// geometry) reads.
std::uint64_t padded_elements(const Dims& d, const Conv2dParams& p, Conv2dAlgo algo,
                              const DeviceTraits& tr) {
  ConvPush c = push_of(d, p);
  set_padded(c, padded_tile(c, algo, tr));
  return std::uint64_t(d.n) * std::uint64_t(d.cin) * c.hp * c.wp;
}

// The pointwise kernel's tile: px pixels × co output channels per
// invocation, the input-channel loop unrolled by `unroll`. Measured on
// lavapipe (landmark-net shapes 32→32 at 56² to 256→256 at 7², process CPU
// time, 2026-12-03): unrolling by 4 cut 14–20 %; fetching a step's channels
// first and then updating each accumulator once for all of them another
// 15–25 % (the JIT-compiled code, read with perf: the CO·PX accumulators live
// on the stack, and each update is a load, a blend under the loop's lane
// mask and a store); 16 channels (each input fetch feeds twice the FMAs)
// 2–9 %; 16 pixels instead of 8 5–15 % alone on the landmark and detector
// shapes (56² to 7², 208² to 13²), but in the landmark net only on its 56²
// and 28² layers (whole forward passes, variants interleaved).
struct PointwiseTile {
  std::uint32_t co = kCoBlock, unroll = 1, px = kPx;
};

PointwiseTile pointwise_tile(const ConvPush& c, const DeviceTraits& tr) {
  PointwiseTile t;
  // 16 channels read two 8-channel blocks of the packed weights: only when
  // both exist (cout a multiple of 16).
  if (c.cout % (2 * kCoBlock) == 0) t.co = 2 * kCoBlock;
  // 16 pixels on planes of 512 or more (landmark net: 28² and 56²; 14² and
  // 7² ran slower in the net).
  if (tr.pointwise_wide_min_pixels > 0 &&
      std::uint64_t(c.h) * c.w >= tr.pointwise_wide_min_pixels) {
    t.px = 2 * kPx;
  }
  for (std::uint32_t u : {4u, 2u}) {
    if (c.cin % u == 0) {
      t.unroll = u;
      break;
    }
  }
  return t;
}

// The backward kernels differentiate conv(x), not conv(relu(x)).
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

// Empty string when `algo` can run these shapes, else why not.
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

// OIHW (or, transposed, the [Cin][Cout] weight of the conv whose backward-data
// this is, flipped) → [Cout/8][Cin][KH][KW][8].
Tensor pack_weights(Stream& stream, const Tensor& weight, const ConvPush& c, bool transposed) {
  const std::uint64_t n = std::uint64_t(div_up(c.cout, kCoBlock)) * c.cin * c.kh * c.kw * kCoBlock;
  Tensor packed = Tensor::empty(stream.device(), Shape{std::int64_t(n)});
  stream.dispatch(kPack, {texel(weight), out(packed)}, c,
                  groups_1d(div_up(n, 256), stream.device().info()), {transposed ? 1u : 0u});
  return packed;
}

// Zero-padded copy of x for the blocked/depthwise kernels (c has set_padded()).
Tensor pad_input(Stream& stream, const Tensor& x, const ConvPush& c) {
  const std::uint64_t n = std::uint64_t(c.n) * c.cin * c.hp * c.wp;
  Tensor xp = Tensor::empty(stream.device(), Shape{std::int64_t(n)});
  // Each workgroup loops over planes: llvmpipe pays per workgroup, so a few
  // dozen groups (enough for every CPU thread) beat one per plane.
  const std::uint32_t planes = c.n * c.cin;
  const std::uint32_t gx = div_up(c.wp / 4, 16u), gy = div_up(c.hp, 4u);
  const std::uint32_t gz = std::clamp<std::uint32_t>(
      kPadGroups / (gx * gy), 1u, std::min(planes, stream.device().info().max_workgroup_count[2]));
  const Groups g{gx, gy, gz};
  stream.dispatch(kPad, {texel(x), out(xp)}, c, g);
  return xp;
}

// y's planes in c: a padded tensor's (the output written into its interior).
void set_y_padded(ConvPush& c, const Conv2dPadded& y) {
  c.yh = y.hp;
  c.yw = y.wp;
  c.ytop = std::uint32_t(y.top);
  c.yleft = std::uint32_t(y.left);
}

// The forward dispatch of one variant; c has everything but the padded geometry.
// prepacked: the weight already packed (conv2d_pack_weight), else packed here.
// residual: [N, cres, Hout, Wout] added before the activation, or nullptr.
// x_padded (blocked, depthwise): x's padded copy already made (x is then not
// read); y_padded (blocked, depthwise, pointwise): the padded tensor to write
// the output into instead of y; residual_padded (blocked: in x's padded
// layout; pointwise: any padded layout), read instead of residual.
void run_forward(Stream& stream, Conv2dAlgo algo, const Tensor& x, const Tensor& weight,
                 const Tensor* bias, const Tensor& y, ConvPush c, bool transposed_weight,
                 const Tensor* prepacked = nullptr, const Tensor* residual = nullptr,
                 const Conv2dPadded* x_padded = nullptr, const Conv2dPadded* y_padded = nullptr,
                 const Conv2dPadded* residual_padded = nullptr) {
  const DeviceInfo& info = stream.device().info();
  const DeviceTraits& tr = stream.device().traits();
  const Tensor& b = bias != nullptr ? *bias : weight;  // unused binding when has_bias == 0
  c.has_bias = bias != nullptr ? 1u : 0u;
  const Tensor& r_plain = residual != nullptr ? *residual : weight;  // unused when has_res == 0
  c.has_res = residual != nullptr ? 1u : 0u;
  c.cres = residual != nullptr ? std::uint32_t(residual->shape()[1]) : 0u;
  if (residual_padded != nullptr) {
    c.has_res = 2;
    c.cres = std::uint32_t(residual_padded->shape[1]);
  }
  const Tensor& r = residual_padded != nullptr ? residual_padded->data : r_plain;
  if (y_padded != nullptr) set_y_padded(c, *y_padded);
  const Tensor& yt = y_padded != nullptr ? y_padded->data : y;
  switch (algo) {
    case Conv2dAlgo::auto_select:
    case Conv2dAlgo::direct: {
      const std::uint64_t n = std::uint64_t(c.n) * c.cout * c.hout * c.wout;
      // Specialization constants are positional: ids 0..7 are unused here, 8 is HAS_RES.
      stream.dispatch(kDirect, {texel(x), texel(weight), texel(b), out(y), texel(r)}, c,
                      groups_1d(div_up(n, 256), info), {0, 0, 0, 0, 0, 0, 0, 0, c.has_res});
      return;
    }
    case Conv2dAlgo::pointwise: {
      const Tensor packed =
          prepacked != nullptr ? *prepacked : pack_weights(stream, weight, c, transposed_weight);
      if (residual_padded != nullptr) {  // the shader reads it in the (hp, wp, pt, pl) layout
        c.hp = residual_padded->hp;
        c.wp = residual_padded->wp;
        c.pt = residual_padded->top;
        c.pl = residual_padded->left;
      }
      // (pixel block, channel block) pairs, flattened (the shader splits them).
      const bool vec4 = (std::uint64_t(c.h) * c.w) % 4 == 0;
      const PointwiseTile t = pointwise_tile(c, tr);
      const std::uint64_t blocks =
          div_up(std::uint64_t(c.h) * c.w, std::uint64_t(t.px)) * div_up(c.cout, t.co);
      const std::uint32_t wg = group_lanes(blocks * c.n, tr.min_workgroups, kBlockedGroup);
      Groups g = groups_1d(div_up(blocks, wg), info);
      g.z = c.n;
      // y by quads of pixels (the shader's STORE4): plain, or padded with aligned rows.
      const bool store4 =
          vec4 && (y_padded == nullptr || (c.w % 4 == 0 && c.yw % 4 == 0 && c.yleft % 4 == 0));
      // The residual by quads too (RES4): plain, or padded with aligned rows.
      const bool res4 =
          store4 &&
          (c.has_res == 1 || (c.has_res == 2 && c.w % 4 == 0 && c.wp % 4 == 0 && c.pl % 4 == 0));
      stream.dispatch(kPointwise,
                      {texel(x, vec4 ? VK_FORMAT_R32G32B32A32_SFLOAT : VK_FORMAT_R32_SFLOAT),
                       texel(packed, VK_FORMAT_R32G32B32A32_SFLOAT), texel(b), out(yt),
                       texel(r, res4 ? VK_FORMAT_R32G32B32A32_SFLOAT : VK_FORMAT_R32_SFLOAT)},
                      c, g,
                      {vec4 ? 1u : 0u, wg, store4 ? 1u : 0u, res4 ? 1u : 0u, t.px, t.co, t.unroll,
                       0, c.has_res});
      return;
    }
    case Conv2dAlgo::blocked: {
      const BlockedTile t = blocked_tile(c, tr);
      set_padded(c, t);
      const Tensor packed =
          prepacked != nullptr ? *prepacked : pack_weights(stream, weight, c, transposed_weight);
      const Tensor xp = x_padded != nullptr ? x_padded->data : pad_input(stream, x, c);
      // (pixel block, channel block) pairs, flattened (the shader splits them).
      const std::uint64_t blocks =
          std::uint64_t(div_up(c.hout, t.ry)) * c.wblocks * div_up(c.cout, 4 * t.cg);
      const std::uint32_t wg = group_lanes(blocks * c.n, tr.min_workgroups, kBlockedGroup);
      Groups g = groups_1d(div_up(blocks, wg), info);
      g.z = c.n;
      // y by quads of pixels (the shader's STORE4): blocks and rows 4-aligned.
      const bool store4 = t.px % 4 == 0 && c.wout % 4 == 0 && c.yw % 4 == 0 && c.yleft % 4 == 0;
      stream.dispatch(kBlocked,
                      {texel(xp, VK_FORMAT_R32G32B32A32_SFLOAT),
                       texel(packed, VK_FORMAT_R32G32B32A32_SFLOAT), texel(b), out(yt), texel(r)},
                      c, g,
                      {c.kh, c.kw, c.sx, c.dx, t.px, t.cg, t.ry, wg, c.has_res, store4 ? 1u : 0u});
      return;
    }
    case Conv2dAlgo::depthwise: {
      const BlockedTile t = depthwise_tile(c, tr);
      set_padded(c, t);
      c.pl += std::int32_t(t.sh);  // where pad_input puts x (the shader does not read pl)
      const Tensor xp = x_padded != nullptr ? x_padded->data : pad_input(stream, x, c);
      // (pixel block, channel) pairs, flattened (the shader splits them).
      const std::uint64_t blocks = std::uint64_t(div_up(c.hout, t.ry)) * c.wblocks * c.cout;
      const std::uint32_t wg = group_lanes(blocks * c.n, tr.min_workgroups, kBlockedGroup);
      Groups g = groups_1d(div_up(blocks, wg), info);
      g.z = c.n;
      // y by quads of pixels (the shader's STORE4): 1, whole aligned quads in
      // every row; else 2, a plain y and blocks of whole rows, whose outputs
      // are contiguous (14² planes: 7 vec4 stores per block instead of 28).
      std::uint32_t store4 = 0;
      if (t.px % 4 == 0 && c.wout % 4 == 0 && c.yw % 4 == 0 && c.yleft % 4 == 0) {
        store4 = 1;
      } else if (c.yh == c.hout && c.yw == c.wout && c.ytop == 0 && c.yleft == 0 &&
                 t.px == c.wout && (t.ry * t.px) % 4 == 0 && (c.hout * c.wout) % 4 == 0 &&
                 c.hout % t.ry == 0) {
        store4 = 2;
      }
      // The weights as vec4 texels (the shader's WVEC4) when they fill whole texels.
      const bool wvec4 = weight.numel() % 4 == 0;
      stream.dispatch(kDepthwise,
                      {texel(xp, VK_FORMAT_R32G32B32A32_SFLOAT),
                       texel(weight, wvec4 ? VK_FORMAT_R32G32B32A32_SFLOAT : VK_FORMAT_R32_SFLOAT),
                       texel(b), out(yt), texel(r)},
                      c, g,
                      {c.kh, c.kw, c.sx, c.dx, t.px, t.ry, c.xrelu, wg, c.has_res, t.sh, store4,
                       wvec4 ? 1u : 0u});
      return;
    }
  }
}

}  // namespace

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
  const Dims d = dims_of("conv2d_output_shape", x, weight, p);
  return Shape{d.n, d.cout, d.hout, d.wout};
}

Conv2dAlgo conv2d_select(const Device& device, const Shape& x, const Shape& weight,
                         const Conv2dParams& p) {
  return select(device, dims_of("conv2d_select", x, weight, p), p, "conv2d_select");
}

bool conv2d_uses_packed_weight(Conv2dAlgo algo) noexcept {
  return algo == Conv2dAlgo::blocked || algo == Conv2dAlgo::pointwise;
}

Conv2dPackedWeight conv2d_pack_weight(Stream& stream, const Tensor& weight) {
  const char* op = "conv2d_pack_weight";
  require_f32_rank(weight, 4, op, "weight");
  const Shape& s = weight.shape();
  if (weight.numel() == 0) {
    throw InvalidArgument(op, "weight " + s.str() + " is empty", "pass a non-empty OIHW weight");
  }
  ConvPush c{};
  c.cout = std::uint32_t(s[0]);
  c.cin = std::uint32_t(s[1]);
  c.kh = std::uint32_t(s[2]);
  c.kw = std::uint32_t(s[3]);
  return Conv2dPackedWeight{pack_weights(stream, weight, c, false), s};
}

namespace {

// The padded input geometry the blocked or depthwise kernel reads for these shapes.
Conv2dPadded padded_layout(const Dims& d, const Conv2dParams& p, const Shape& x, Conv2dAlgo algo,
                           const DeviceTraits& tr) {
  ConvPush c = push_of(d, p);
  const BlockedTile t = padded_tile(c, algo, tr);
  set_padded(c, t);
  Conv2dPadded l;
  l.shape = x;
  l.hp = c.hp;
  l.wp = c.wp;
  l.top = p.pad.top;
  l.left = p.pad.left + std::int32_t(t.sh);
  return l;
}

bool same_layout(const Conv2dPadded& a, const Conv2dPadded& b) {
  return a.shape == b.shape && a.hp == b.hp && a.wp == b.wp && a.top == b.top && a.left == b.left;
}

// conv2d's checks and dispatch. x_padded: x's padded copy (x_shape is then
// its shape and x unused); y_padded: written instead of y; residual_padded:
// read instead of residual.
void forward(Stream& stream, const char* op, const Tensor& x, const Tensor& weight,
             const Tensor* bias, const Tensor* y, const Conv2dParams& p,
             const Conv2dPackedWeight* packed, const Tensor* residual, const Conv2dPadded* x_padded,
             const Conv2dPadded* y_padded, const Conv2dPadded* residual_padded = nullptr) {
  const Shape xs = x_padded != nullptr ? x_padded->shape : x.shape();
  if (x_padded == nullptr) require_f32_rank(x, 4, op, "x");
  require_f32_rank(weight, 4, op, "weight");
  const Dims d = dims_of(op, xs, weight.shape(), p);
  const Shape ys{d.n, d.cout, d.hout, d.wout};
  if (y != nullptr) {
    require_f32(*y, op, "y");
    require_shape(*y, ys, op, "y");
  }
  if (bias != nullptr) {
    require_f32(*bias, op, "bias");
    require_shape(*bias, Shape{d.cout}, op, "bias");
  }
  if (residual != nullptr) {
    require_f32_rank(*residual, 4, op, "residual");
    const Shape& rs = residual->shape();
    if (rs[0] != d.n || rs[1] < 1 || rs[1] > d.cout || rs[2] != d.hout || rs[3] != d.wout) {
      throw InvalidArgument(op,
                            "residual " + rs.str() + " must be [N, C, Hout, Wout] = [" + str(d.n) +
                                ", 1.." + str(d.cout) + ", " + str(d.hout) + ", " + str(d.wout) +
                                "]",
                            "pass a residual with y's batch and size and at most y's channels");
    }
  }
  if (packed != nullptr && packed->defined() && !(packed->weight_shape == weight.shape())) {
    throw InvalidArgument(op,
                          "packed weight was packed from " + packed->weight_shape.str() +
                              ", the weight is " + weight.shape().str(),
                          "pack this weight with conv2d_pack_weight (again after it changed)");
  }
  const Conv2dAlgo algo = select(stream.device(), d, p, op);
  const bool reads_padded = algo == Conv2dAlgo::blocked || algo == Conv2dAlgo::depthwise;
  const bool blocked = algo == Conv2dAlgo::blocked, pointwise = algo == Conv2dAlgo::pointwise;
  const auto refuse = [&](const char* what, const char* variants) {
    throw InvalidArgument(
        op,
        std::string(what) + " needs the " + variants + " variant, not " + conv2d_algo_name(algo),
        "use conv2d (conv2d_padded_input is undefined for such convolutions)");
  };
  if (x_padded != nullptr && !reads_padded) refuse("a padded input", "blocked or depthwise");
  if (y_padded != nullptr && !reads_padded && !pointwise) {
    refuse("a padded output", "blocked, depthwise or pointwise");
  }
  if (residual_padded != nullptr && !blocked && !pointwise) {
    refuse("a padded residual", "blocked or pointwise");
  }
  if (residual_padded != nullptr) {
    const Conv2dPadded& r = *residual_padded;
    const bool holds = residual == nullptr && r.defined() && r.shape.rank() == 4 &&
                       r.shape[0] == d.n && r.shape[1] >= 1 && r.shape[1] <= d.cout &&
                       r.shape[2] == d.hout && r.shape[3] == d.wout && r.top >= 0 && r.left >= 0 &&
                       std::int64_t(r.hp) >= r.top + d.hout &&
                       std::int64_t(r.wp) >= r.left + d.wout &&
                       r.data.numel() == d.n * r.shape[1] * std::int64_t(r.hp) * std::int64_t(r.wp);
    if (blocked) {
      // In x's padded layout: y must have x's size (a stride-1 'same' conv).
      const Conv2dPadded want = padded_layout(d, p, xs, algo, stream.device().traits());
      const bool fits = holds && d.hout == d.h && d.wout == d.w && r.hp == want.hp &&
                        r.wp == want.wp && r.top == want.top && r.left == want.left;
      if (!fits) {
        throw InvalidArgument(op, "the padded residual is not in this convolution's input layout",
                              "pass one residual, padded like x (conv2d_padded_input for x's "
                              "shape), for a convolution whose output has x's size");
      }
    } else if (!holds) {
      throw InvalidArgument(op,
                            "the padded residual " + r.shape.str() + " (planes " + str(r.hp) + "×" +
                                str(r.wp) + ") does not hold a residual for y " + ys.str(),
                            "pass one residual [N, 1..Cout, Hout, Wout], padded or plain");
    }
  }
  if (x_padded != nullptr) {
    if (!x_padded->defined() ||
        !same_layout(*x_padded, padded_layout(d, p, xs, algo, stream.device().traits()))) {
      throw InvalidArgument(op, "the padded input is not the one this convolution reads",
                            "make it with conv2d_padded_input for the same shapes and params");
    }
  }
  if (y_padded != nullptr) {
    const Conv2dPadded& t = *y_padded;
    // Rows and columns past hp, wp are not written: the consumer reads none.
    const bool fits = t.defined() && t.shape == ys && t.top >= 0 && t.left >= 0 &&
                      t.data.numel() == d.n * d.cout * std::int64_t(t.hp) * std::int64_t(t.wp);
    if (!fits) {
      throw InvalidArgument(op, "the padded output does not hold y " + ys.str(),
                            "make it with conv2d_padded_input for the consumer of y");
    }
  }
  const Tensor* prepacked =
      packed != nullptr && packed->defined() && conv2d_uses_packed_weight(algo) ? &packed->packed
                                                                                : nullptr;
  const Tensor& xt = x_padded != nullptr ? x_padded->data : x;
  const Tensor& yt = y != nullptr ? *y : y_padded->data;
  run_forward(stream, algo, xt, weight, bias, yt, push_of(d, p), false, prepacked, residual,
              x_padded, y_padded, residual_padded);
}

}  // namespace

void conv2d(Stream& stream, const Tensor& x, const Tensor& weight, const Tensor* bias,
            const Tensor& y, const Conv2dParams& p, const Conv2dPackedWeight* packed,
            const Tensor* residual) {
  forward(stream, "conv2d", x, weight, bias, &y, p, packed, residual, nullptr, nullptr);
}

Conv2dPadded conv2d_padded_input(Stream& stream, const Shape& x, const Shape& weight,
                                 const Conv2dParams& p) {
  const char* op = "conv2d_padded_input";
  const Dims d = dims_of(op, x, weight, p);
  const Conv2dAlgo algo = select(stream.device(), d, p, op);
  if (algo != Conv2dAlgo::blocked && algo != Conv2dAlgo::depthwise) return {};
  Conv2dPadded l = padded_layout(d, p, x, algo, stream.device().traits());
  l.data =
      Tensor::empty(stream.device(), Shape{d.n * d.cin * std::int64_t(l.hp) * std::int64_t(l.wp)});
  stream.fill(l.data, 0.f);
  return l;
}

void conv2d_into_padded(Stream& stream, const Tensor& x, const Tensor& weight, const Tensor* bias,
                        const Conv2dPadded& y, const Conv2dParams& p,
                        const Conv2dPackedWeight* packed, const Tensor* residual) {
  forward(stream, "conv2d_into_padded", x, weight, bias, nullptr, p, packed, residual, nullptr, &y);
}

void conv2d_padded(Stream& stream, const Tensor* x, const Tensor& weight, const Tensor* bias,
                   const Tensor* y, const Conv2dParams& p, const Conv2dPaddedIo& io,
                   const Conv2dPackedWeight* packed, const Tensor* residual) {
  const char* op = "conv2d_padded";
  if ((x == nullptr) == (io.x == nullptr) || (y == nullptr) == (io.y == nullptr)) {
    throw InvalidArgument(op, "x and y must each be given once: plain or padded",
                          "pass either the tensor or its padded form");
  }
  const Tensor& xt = x != nullptr ? *x : io.x->data;
  forward(stream, op, xt, weight, bias, y, p, packed, residual, io.x, io.y, io.residual);
}

void conv2d_from_padded(Stream& stream, const Conv2dPadded& x, const Tensor& weight,
                        const Tensor* bias, const Tensor& y, const Conv2dParams& p,
                        const Conv2dPackedWeight* packed, const Tensor* residual) {
  forward(stream, "conv2d_from_padded", x.data, weight, bias, &y, p, packed, residual, &x, nullptr);
}

void conv2d_backward_data(Stream& stream, const Tensor& dy, const Tensor& weight, const Tensor& dx,
                          const Conv2dParams& p) {
  const char* op = "conv2d_backward_data";
  refuse_relu_input(op, p);
  require_f32_rank(dx, 4, op, "dx");
  require_f32_rank(weight, 4, op, "weight");
  const Dims d = dims_of(op, dx.shape(), weight.shape(), p);
  require_f32(dy, op, "dy");
  require_shape(dy, Shape{d.n, d.cout, d.hout, d.wout}, op, "dy");

  // Stride 1, groups 1: dX = conv(dY, W'), W'[ci][co] = W[co][ci] flipped in
  // both axes, padding (K−1)·d − pad (may be negative: the pad pass crops).
  Conv2dParams tp;
  tp.dilation_y = p.dilation_y;
  tp.dilation_x = p.dilation_x;
  const bool transposable =
      p.groups == 1 && p.stride_y == 1 && p.stride_x == 1 && small_kernel(d, tp);
  const bool use_blocked =
      p.algo == Conv2dAlgo::blocked || (p.algo == Conv2dAlgo::auto_select && transposable);
  if (p.algo != Conv2dAlgo::auto_select && p.algo != Conv2dAlgo::direct &&
      !(p.algo == Conv2dAlgo::blocked && transposable)) {
    throw InvalidArgument(
        op, std::string("variant ") + conv2d_algo_name(p.algo) + " cannot run this backward-data",
        "use auto_select or direct (blocked needs stride 1 and groups 1)");
  }
  if (use_blocked) {
    ConvPush c{};
    c.n = std::uint32_t(d.n);
    c.cin = std::uint32_t(d.cout);
    c.h = std::uint32_t(d.hout);
    c.w = std::uint32_t(d.wout);
    c.cout = std::uint32_t(d.cin);
    c.hout = std::uint32_t(d.h);
    c.wout = std::uint32_t(d.w);
    c.kh = std::uint32_t(d.kh);
    c.kw = std::uint32_t(d.kw);
    c.sy = c.sx = 1;
    c.dy = std::uint32_t(p.dilation_y);
    c.dx = std::uint32_t(p.dilation_x);
    c.pt = std::int32_t((d.kh - 1) * p.dilation_y - p.pad.top);
    c.pl = std::int32_t((d.kw - 1) * p.dilation_x - p.pad.left);
    c.groups = 1;
    c.cin_g = c.cin;
    c.cout_g = c.cout;
    c.yh = c.hout;
    c.yw = c.wout;
    const std::string why =
        padded_elements(Dims{d.n, d.cout, d.hout, d.wout, d.cin, d.kh, d.kw, d.h, d.w}, tp,
                        Conv2dAlgo::blocked,
                        stream.device().traits()) > stream.device().info().max_texel_buffer_elements
            ? "the padded input exceeds the texel limit"
            : "";
    if (why.empty()) {
      run_forward(stream, Conv2dAlgo::blocked, dy, weight, nullptr, dx, c, true);
      return;
    }
    if (p.algo == Conv2dAlgo::blocked) throw InvalidArgument(op, why, "use auto_select");
  }
  const ConvPush c = push_of(d, p);
  const std::uint64_t n = std::uint64_t(d.n) * d.cin * d.h * d.w;
  stream.dispatch(kBwdData, {texel(dy), texel(weight), out(dx)}, c,
                  groups_1d(div_up(n, 256), stream.device().info()));
}

void conv2d_backward_weight(Stream& stream, const Tensor& x, const Tensor& dy,
                            const Tensor& dweight, const Tensor* dbias, const Conv2dParams& p) {
  const char* op = "conv2d_backward_weight";
  refuse_relu_input(op, p);
  require_f32_rank(x, 4, op, "x");
  require_f32_rank(dweight, 4, op, "dweight");
  const Dims d = dims_of(op, x.shape(), dweight.shape(), p);
  require_f32(dy, op, "dy");
  require_shape(dy, Shape{d.n, d.cout, d.hout, d.wout}, op, "dy");
  if (dbias != nullptr) {
    require_f32(*dbias, op, "dbias");
    require_shape(*dbias, Shape{d.cout}, op, "dbias");
  }
  const DeviceInfo& info = stream.device().info();
  ConvPush c = push_of(d, p);
  // groups == 1: the blocked kernel over zero-padded x and dy; else (or when
  // p.algo == direct) one dw element per invocation.
  const bool blocked =
      p.algo != Conv2dAlgo::direct && why_not(Conv2dAlgo::blocked, stream.device(), d, p).empty();
  if (blocked) {
    set_padded(c);
    const Tensor xp = pad_input(stream, x, c);
    ConvPush dc = c;  // dy [n, cout, hout, wout] → [n, cout, hout, wblocks·8]
    dc.cin = c.cout;
    dc.h = dc.hp = c.hout;
    dc.w = c.wout;
    dc.wp = c.wblocks * kPx;
    dc.pt = dc.pl = 0;
    const Tensor dyp = pad_input(stream, dy, dc);
    stream.dispatch(
        kBwdWeightBlocked,
        {texel(xp, VK_FORMAT_R32G32B32A32_SFLOAT), texel(dyp, VK_FORMAT_R32G32B32A32_SFLOAT),
         out(dweight)},
        c, Groups{div_up(std::uint64_t(c.cin) * c.kh, kBlockedGroup), div_up(c.cout, kCoBlock), 1},
        {c.kw, c.sx, c.dx});
  } else {
    stream.dispatch(kBwdWeight, {texel(x), texel(dy), out(dweight)}, c,
                    groups_1d(div_up(std::uint64_t(dweight.numel()), 64), info));
  }
  if (dbias != nullptr) {
    require_subgroup_arithmetic(stream, op);
    stream.dispatch(kBwdBias, {texel(dy), out(*dbias)}, c, groups_1d(d.cout, info));
  }
}

}  // namespace vkjr2::kernels
