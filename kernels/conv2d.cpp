#include <vkjr2/kernels/check.hpp>
#include <vkjr2/kernels/conv2d.hpp>

#include <algorithm>
#include <string>

#include "internal/conv2d_impl.hpp"

namespace vkjr2::kernels {
namespace detail {
namespace {

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

// y's planes in c: a padded tensor's (the output written into its interior).
void set_y_padded(ConvPush& c, const PlaneLayout& y) {
  c.yh = y.hp;
  c.yw = y.wp;
  c.ytop = std::uint32_t(y.top);
  c.yleft = std::uint32_t(y.left);
}

}  // namespace

Tensor pack_weights(Stream& stream, const Tensor& weight, const ConvPush& c, bool transposed) {
  const std::uint64_t n = std::uint64_t(div_up(c.cout, kCoBlock)) * c.cin * c.kh * c.kw * kCoBlock;
  Tensor packed = Tensor::empty(stream.device(), Shape{std::int64_t(n)});
  stream.dispatch(kPack, {texel(weight), out(packed)}, c,
                  groups_1d(div_up(n, 256), stream.device().info()), {transposed ? 1u : 0u});
  return packed;
}

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
  // Whole quads of x (shaders/conv2d_pad.comp, VEC4) when its rows are.
  if (c.w % 4 == 0 && x.vk_offset() % 16 == 0) {
    const auto shift = std::uint32_t(((-c.pl) % 4 + 4) % 4);
    stream.dispatch(kPad, {texel(x, VK_FORMAT_R32G32B32A32_SFLOAT), out(xp)}, c, g, {1u, shift});
    return xp;
  }
  stream.dispatch(kPad, {texel(x), out(xp)}, c, g, {0u, 0u});
  return xp;
}

void run_forward(Stream& stream, Conv2dAlgo algo, const Tensor& x, const Tensor& weight,
                 const Tensor* bias, const Tensor& y, ConvPush c, bool transposed_weight,
                 const Tensor* prepacked, const Tensor* residual, const Planes* x_padded,
                 const Planes* y_padded, const Planes* residual_padded) {
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
  if (y_padded != nullptr) set_y_padded(c, y_padded->layout);
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
        c.hp = residual_padded->layout.hp;
        c.wp = residual_padded->layout.wp;
        c.pt = residual_padded->layout.top;
        c.pl = residual_padded->layout.left;
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

}  // namespace detail

void Conv2dPlan::run(Stream& stream, const Planes& x, const Tensor& weight, const Tensor* bias,
                     const Planes& y, const Planes* residual) const {
  using detail::str;
  const char* op = "conv2d";
  if (!defined()) throw InvalidArgument(op, "the plan is empty", "make it for the convolution");
  if (!made_for(stream.device())) {
    throw InvalidArgument(op, "the plan was made for another device",
                          "make a plan per device (its choices follow the device's traits)");
  }
  const auto refuse = [&](const std::string& what, const std::string& fix) {
    throw InvalidArgument(op, what, fix);
  };
  if (!(x.shape == x_)) {
    refuse("x has shape " + x.shape.str() + ", expected the plan's input " + x_.str(),
           "make a plan for this input shape");
  }
  if (x.padded()) {
    if (!(x.layout == input_layout_) ||
        x.data.numel() != x_[0] * x_[1] * std::int64_t(x.layout.hp) * std::int64_t(x.layout.wp)) {
      refuse("the padded input (" + x.layout.str() + ") is not the one this convolution reads (" +
                 input_layout_.str() + ")",
             "make it with Planes::make(stream, x, plan.input_layout()), or pass x plain");
    }
  } else {
    require_f32(x.data, op, "x");
    require_shape(x.data, x_, op, "x");
  }
  require_f32(weight, op, "weight");
  require_shape(weight, weight_, op, "weight");
  if (!(y.shape == y_)) {
    refuse("y has shape " + y.shape.str() + ", expected the convolution's output " + y_.str(),
           "pass y of the plan's output_shape()");
  }
  if (y.padded()) {
    if (!writes_padded()) {
      refuse(
          std::string("a padded output needs the blocked, depthwise or pointwise variant, not ") +
              conv2d_algo_name(algo_),
          "pass y plain");
    }
    // Rows and columns past hp, wp are not written: the consumer reads none.
    if (y.layout.top < 0 || y.layout.left < 0 ||
        y.data.numel() != y_[0] * y_[1] * std::int64_t(y.layout.hp) * std::int64_t(y.layout.wp)) {
      refuse("the padded output (" + y.layout.str() + ", data " + y.data.shape().str() +
                 ") does not hold y " + y_.str(),
             "make it with Planes::make for the consumer's input layout");
    }
  } else {
    require_f32(y.data, op, "y");
    require_shape(y.data, y_, op, "y");
  }
  if (bias != nullptr) {
    require_f32(*bias, op, "bias");
    require_shape(*bias, Shape{y_[1]}, op, "bias");
  }
  if (residual != nullptr) {
    const std::string why = residual_misfit(*residual);
    if (!why.empty()) {
      refuse(why,
             "pass one residual [N, 1..Cout, Hout, Wout], plain or in a layout the variant "
             "reads");
    }
  }
  const Tensor* plain_residual =
      residual != nullptr && !residual->padded() ? &residual->data : nullptr;
  const Planes* padded_residual = residual != nullptr && residual->padded() ? residual : nullptr;
  const detail::Dims d = detail::dims_of(op, x_, weight_, p_);
  detail::run_forward(stream, algo_, x.data, weight, bias, y.data, detail::push_of(d, p_), false,
                      packed_.defined() ? &packed_ : nullptr, plain_residual,
                      x.padded() ? &x : nullptr, y.padded() ? &y : nullptr, padded_residual);
}

void conv2d(Stream& stream, const Tensor& x, const Tensor& weight, const Tensor* bias,
            const Tensor& y, const Conv2dParams& p, const Tensor* residual) {
  const char* op = "conv2d";
  require_f32_rank(x, 4, op, "x");
  require_f32_rank(weight, 4, op, "weight");
  const Conv2dPlan plan(stream.device(), x.shape(), weight.shape(), p);
  if (residual != nullptr) require_f32_rank(*residual, 4, op, "residual");
  const Planes r = residual != nullptr ? Planes::of(*residual) : Planes();
  plan.run(stream, Planes::of(x), weight, bias, Planes::of(y), residual != nullptr ? &r : nullptr);
}

}  // namespace vkjr2::kernels
