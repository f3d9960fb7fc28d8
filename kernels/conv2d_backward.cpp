#include <vkjr2/kernels/check.hpp>
#include <vkjr2/kernels/conv2d.hpp>
#include <vkjr2/kernels/layout.hpp>

#include <string>

#include "internal/conv2d_impl.hpp"

namespace vkjr2::kernels {
namespace {

using namespace detail;

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

// The checks both backward passes make: the input-shaped tensor (x or dx)
// and the weight-shaped one against p, dy of the output's shape.
Dims backward_dims(const char* op, const Tensor& in, const char* in_name, const Tensor& weight,
                   const char* weight_name, const Tensor& dy, const Conv2dParams& p) {
  refuse_relu_input(op, p);
  require_f32_rank(in, 4, op, in_name);
  require_f32_rank(weight, 4, op, weight_name);
  const Dims d = dims_of(op, in.shape(), weight.shape(), p);
  require_f32(dy, op, "dy");
  require_shape(dy, Shape{d.n, d.cout, d.hout, d.wout}, op, "dy");
  return d;
}

}  // namespace

void conv2d_backward_data(Stream& stream, const Tensor& dy, const Tensor& weight, const Tensor& dx,
                          const Conv2dParams& p) {
  const char* op = "conv2d_backward_data";
  const Dims d = backward_dims(op, dx, "dx", weight, "weight", dy, p);

  // 1×1, stride 1, no padding, groups 1: dX = Wᵀ·dY per pixel, the pointwise
  // kernel over dY with the transposed weight (no padding pass).
  if (p.algo == Conv2dAlgo::auto_select &&
      why_not(Conv2dAlgo::pointwise, stream.device(), d, p).empty()) {
    const Dims td{d.n, d.cout, d.hout, d.wout, d.cin, d.kh, d.kw, d.h, d.w};
    run_forward(stream, Conv2dAlgo::pointwise, dy, weight, nullptr, dx, push_of(td, Conv2dParams{}),
                true);
    return;
  }

  // Depthwise (one output per input channel), stride 1: dX = the depthwise
  // conv of dY with the weight rotated by 180°, padding (K−1)·d − pad.
  if (p.algo == Conv2dAlgo::auto_select && p.groups == d.cin && d.cout == d.cin &&
      p.stride_y == 1 && p.stride_x == 1) {
    const Dims td{d.n, d.cout, d.hout, d.wout, d.cin, d.kh, d.kw, d.h, d.w};
    Conv2dParams dp;
    dp.dilation_y = p.dilation_y;
    dp.dilation_x = p.dilation_x;
    dp.groups = int(d.cout);
    dp.pad.top = int((d.kh - 1) * p.dilation_y - p.pad.top);
    dp.pad.left = int((d.kw - 1) * p.dilation_x - p.pad.left);
    dp.pad.bottom = int((d.kh - 1) * p.dilation_y - p.pad.bottom);
    dp.pad.right = int((d.kw - 1) * p.dilation_x - p.pad.right);
    const bool non_negative =
        dp.pad.top >= 0 && dp.pad.left >= 0 && dp.pad.bottom >= 0 && dp.pad.right >= 0;
    if (non_negative && why_not(Conv2dAlgo::depthwise, stream.device(), td, dp).empty()) {
      // The rotated weight is a temporary: kept alive by the stream until it has run.
      const Tensor rotated = Tensor::empty(stream.device(), weight.shape());
      flip_spatial(stream, weight, rotated);
      run_forward(stream, Conv2dAlgo::depthwise, dy, rotated, nullptr, dx, push_of(td, dp), false);
      return;
    }
  }

  // Stride s ≥ 2 (both axes), groups 1, dilation 1: the phase decomposition.
  // With j = i + pad = s·q + r, dX[i] = Σ_m W[r + s·m] dY[q − m]: for each
  // phase r a stride-1 "full" correlation of dY with the sub-kernel
  // W[r::s] — the transposed blocked conv below with padding K_r − 1. The
  // sub-kernels of all s² phases side by side are pixel_unshuffle(s) of the
  // weight [Cout, Cin, K', K'] zero-padded to a multiple of s: channel
  // c·s² + ry·s + rx holds W[·, c, ry::s, rx::s]. One conv gives
  // every phase of every channel in that order, pixel_shuffle(s) interleaves
  // them into dX shifted by pad, and a slice takes dX.
  const std::int64_t st = p.stride_y;
  if (p.algo == Conv2dAlgo::auto_select && p.groups == 1 && st >= 2 && st <= 4 &&
      p.stride_x == st && p.dilation_y == 1 && p.dilation_x == 1) {
    const std::int64_t kr_y = (d.kh + st - 1) / st, kr_x = (d.kw + st - 1) / st;
    const std::int64_t qy = (p.pad.top + d.h + st - 1) / st;
    const std::int64_t qx = (p.pad.left + d.w + st - 1) / st;
    const Dims td{d.n, d.cout, d.hout, d.wout, d.cin * st * st, kr_y, kr_x, qy, qx};
    Conv2dParams pp;
    pp.pad.top = int(kr_y - 1);
    pp.pad.left = int(kr_x - 1);
    const std::int64_t max_planes = stream.device().info().max_workgroup_count[2];
    const bool fits = 4 * d.cin <= max_planes && small_kernel(td, pp) &&
                      padded_elements(td, pp, Conv2dAlgo::blocked, stream.device().traits()) <=
                          stream.device().info().max_texel_buffer_elements;
    if (fits) {
      const Device& dev = stream.device();
      // Temporaries: kept alive by the stream until it has run.
      const std::int64_t k2y = kr_y * st, k2x = kr_x * st;
      const Tensor padded_w = Tensor::empty(dev, Shape{d.cout, d.cin, k2y, k2x});
      const Tensor phases_w = Tensor::empty(dev, Shape{d.cout, d.cin * st * st, kr_y, kr_x});
      // In chunks of output channels: the shuffle dispatches one workgroup
      // row per (n, c) plane. A multiple of 4: the views start 16-byte aligned.
      const std::int64_t chunk = max_planes / d.cin / 4 * 4;
      for (std::int64_t c0 = 0; c0 < d.cout; c0 += chunk) {
        const std::int64_t cc = std::min(chunk, d.cout - c0);
        const std::int64_t per = d.cin * k2y * k2x;
        const Tensor pw = padded_w.view(Shape{cc, d.cin, k2y, k2x}, c0 * per);
        pad(stream, weight.view(Shape{cc, d.cin, d.kh, d.kw}, c0 * d.cin * d.kh * d.kw),
            Pad2d{0, int(k2y - d.kh), 0, int(k2x - d.kw)}, 0.f, pw);
        pixel_unshuffle(stream, pw, int(st),
                        phases_w.view(Shape{cc, d.cin * st * st, kr_y, kr_x}, c0 * per));
      }
      const Tensor phases = Tensor::empty(dev, Shape{d.n, d.cin * st * st, qy, qx});
      run_forward(stream, Conv2dAlgo::blocked, dy, phases_w, nullptr, phases, push_of(td, pp),
                  true);
      const Tensor shifted = Tensor::empty(dev, Shape{d.n, d.cin, qy * st, qx * st});
      pixel_shuffle(stream, phases, int(st), shifted);
      slice(stream, shifted, {0, p.pad.top, p.pad.left}, dx);
      return;
    }
  }

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
    // The forward conv of dY [N, Cout, Hout, Wout] into dX [N, Cin, H, W].
    const Dims td{d.n, d.cout, d.hout, d.wout, d.cin, d.kh, d.kw, d.h, d.w};
    tp.pad.top = int((d.kh - 1) * p.dilation_y - p.pad.top);
    tp.pad.left = int((d.kw - 1) * p.dilation_x - p.pad.left);
    const ConvPush c = push_of(td, tp);
    const std::string why = padded_elements(td, tp, Conv2dAlgo::blocked, stream.device().traits()) >
                                    stream.device().info().max_texel_buffer_elements
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
  const Dims d = backward_dims(op, x, "x", dweight, "dweight", dy, p);
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
  // 1×1, stride 1, no padding, groups 1: dW = dY·Xᵀ over the pixels, which
  // is the blocked kernel on x and dy read in place as one row of H·W pixels
  // per plane (no padding passes) when H·W is whole 8-pixel blocks. With W a
  // multiple of 8 the sums run in the padded path's order (same bits).
  const bool flat = blocked && p.algo == Conv2dAlgo::auto_select && d.kh == 1 && d.kw == 1 &&
                    p.stride_y == 1 && p.stride_x == 1 && p.pad.top == 0 && p.pad.left == 0 &&
                    p.pad.bottom == 0 && p.pad.right == 0 && p.groups == 1 &&
                    (std::uint64_t(d.h) * std::uint64_t(d.w)) % kPx == 0;
  if (flat) {
    ConvPush f = c;
    f.h = f.hp = f.hout = 1;
    f.w = f.wp = f.wout = std::uint32_t(d.h * d.w);
    f.wblocks = f.wout / kPx;
    f.pt = f.pl = 0;
    stream.dispatch(
        kBwdWeightBlocked,
        {texel(x, VK_FORMAT_R32G32B32A32_SFLOAT), texel(dy, VK_FORMAT_R32G32B32A32_SFLOAT),
         out(dweight)},
        f, Groups{div_up(std::uint64_t(f.cin), kBlockedGroup), div_up(f.cout, kCoBlock), 1},
        {1u, 1u, 1u});
  } else if (blocked) {
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
