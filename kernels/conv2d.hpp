// 2-D convolution (cross-correlation, as in PyTorch/TF): forward with bias and
// fused activation, backward-data (dX) and backward-weight (dW, dbias).
//
// Layouts (f32, contiguous):
//   x      [N, Cin, H, W]                 (NCHW)
//   weight [Cout, Cin/groups, KH, KW]     (OIHW, as PyTorch). TF.js/Keras HWIO
//          weights must be repacked to OIHW by the caller once at load time.
//          The blocked and pointwise variants read weights repacked to
//          [ceil(Cout/8)][Cin][KH][KW][8]: conv2d() packs them on every call
//          unless it is given the packed form from conv2d_pack_weight()
//          (pack once per weight, again after the weight changed).
//   bias   [Cout] (optional: nullptr)
//   y      [N, Cout, Hout, Wout], Hout = (H + pad_top + pad_bottom - ((KH-1)·dy + 1)) / sy + 1.
//
// y[n,co,oy,ox] = act(bias[co] + Σ_{ci∈group(co), ky, kx}
//                 w[co,ci,ky,kx] · x[n, g·Cin/groups + ci, oy·sy − pad_top + ky·dy,
//                                                          ox·sx − pad_left + kx·dx])
// with zeros outside the image. act: none, ReLU, LeakyReLU(slope) after the bias
// and, when given, the residual r [N, Cr, Hout, Wout] (Cr <= Cout; channels
// co >= Cr get none, as a shortcut zero-padded in channels would give):
//   y[n,co,oy,ox] = act(conv + bias[co] + r[n,co,oy,ox]).
//
// p.relu_input (direct and depthwise variants, forward only): x goes through
// ReLU as it is read, y = act(conv(relu(x)) + ...) (a pre-activation fused
// into the conv; the zero padding stays zero).
//
// Backward: the backward kernels assume NO activation. With a fused activation
// the caller applies the activation's backward to dY first (using the forward
// output y: ReLU/LeakyReLU gradients depend only on sign(y)) and passes the
// result as dy.
//
// Variants (chosen in one place, conv2d_select(); all tested):
//   direct     any parameters; one output per invocation (slow fallback).
//   blocked    groups == 1, KH, KW <= 7, stride_x, dilation_x <= 4: a tile of
//              4 or 8 output channels × 1..25 rows × up to 20 pixels per
//              invocation, chosen per shape (a row of up to 20 pixels is one
//              block, so small planes waste no lanes); the input is
//              zero-padded into a temporary (one cheap pass) and read as vec4
//              texels, weights packed to [Cout/8][Cin][KH][KW][8] (per call,
//              or once with conv2d_pack_weight) and read as vec4 texels; KH/KW/stride_x/
//              dilation_x and the tile are specialization constants. 3×3 64→64
//              128² on lavapipe (shared 2-core machine): 26–32 GFLOP/s; the
//              face ResNet's 35²..2² planes: ~40.
//   pointwise  1×1, stride 1, no padding, groups == 1 (a matmul): 8 or 16
//              channels × 8 or 16 consecutive pixels per invocation (vec4 reads
//              when H·W % 4 == 0), (pixel block, channel block) pairs flattened
//              over the workgroups.
//   depthwise  groups == Cin, Cout a multiple of Cin (channel multiplier): one
//              channel × 1..4 rows × up to 16 pixels per invocation, chosen per
//              shape; padded input as for blocked (its own tile's geometry).
// Backward-data reuses the blocked kernel (flipped, transposed weights) for
// stride 1, groups 1 convolutions, and a direct gather otherwise.
// Temporaries (padded input, packed weights) come from Tensor::empty and are
// kept alive by the Stream.
#pragma once

#include <vkjr2/runtime/stream.hpp>

#include <cstdint>

namespace vkjr2::kernels {

enum class Activation : std::uint8_t { none, relu, leaky_relu };

enum class Conv2dAlgo : std::uint8_t {
  auto_select,  // conv2d_select() picks
  direct,
  blocked,
  pointwise,
  depthwise,
};
const char* conv2d_algo_name(Conv2dAlgo algo) noexcept;

struct Padding2d {
  int top = 0, bottom = 0, left = 0, right = 0;
};

struct Conv2dParams {
  int stride_y = 1, stride_x = 1;
  int dilation_y = 1, dilation_x = 1;
  Padding2d pad;  // explicit, asymmetric allowed
  int groups = 1;
  Activation activation = Activation::none;  // forward only, applied after the bias
  float leaky_slope = 0.2f;                  // LeakyReLU: y = x < 0 ? slope·x : x
  // Forward only, direct and depthwise variants: ReLU on x as it is read.
  bool relu_input = false;
  // Forces a variant (tests, benchmarks); auto_select in normal use. A forced
  // variant that cannot run these parameters throws InvalidArgument.
  Conv2dAlgo algo = Conv2dAlgo::auto_select;
};

// TF "SAME" padding for one axis: total = max((ceil(in/s) − 1)·s + (k−1)·d + 1 − in, 0),
// before = total / 2, after = total − before (the extra pixel goes after).
Padding2d same_padding(std::int64_t in_h, std::int64_t in_w, int kh, int kw, int stride_y,
                       int stride_x, int dilation_y = 1, int dilation_x = 1);

// [N, Cout, Hout, Wout] for x [N, Cin, H, W] and weight [Cout, Cin/groups, KH, KW];
// throws InvalidArgument for inconsistent shapes or parameters.
Shape conv2d_output_shape(const Shape& x, const Shape& weight, const Conv2dParams& p);

// The variant conv2d() runs for these shapes on a device (p.algo when not
// auto_select, after checking it can run them; else InvalidArgument).
Conv2dAlgo conv2d_select(const Device& device, const Shape& x, const Shape& weight,
                         const Conv2dParams& p);

// An OIHW weight in the layout the blocked and pointwise variants read
// ([ceil(Cout/8)][Cin/groups][KH][KW][8], zero for the channels past Cout).
// It is a copy: after the weight changes (an optimizer step, a load) pack it
// again, or conv2d() computes with the old values.
struct Conv2dPackedWeight {
  Tensor packed;       // undefined: not packed
  Shape weight_shape;  // the OIHW shape it was packed from
  bool defined() const noexcept { return packed.defined(); }
};
// Records the packing of weight [Cout, Cin/groups, KH, KW] on `stream`.
Conv2dPackedWeight conv2d_pack_weight(Stream& stream, const Tensor& weight);
// Whether `algo` reads packed weights (blocked, pointwise).
bool conv2d_uses_packed_weight(Conv2dAlgo algo) noexcept;

// y = act(conv(x, weight) + bias + residual). bias may be nullptr. packed:
// weight packed by conv2d_pack_weight (used when the selected variant reads
// packed weights; its shape must be weight's), or nullptr to pack on this
// call. residual: [N, Cr, Hout, Wout] with 1 <= Cr <= Cout, a tensor other
// than y, or nullptr (every variant takes it: a residual block's add and
// ReLU in the conv's epilogue). Its gradient is the pre-activation dy
// (channels < Cr).
void conv2d(Stream& stream, const Tensor& x, const Tensor& weight, const Tensor* bias,
            const Tensor& y, const Conv2dParams& p, const Conv2dPackedWeight* packed = nullptr,
            const Tensor* residual = nullptr);

// The zero-padded copy of an input that the blocked and depthwise variants
// read: planes of hp × wp (wp % 4 == 0) with x at (top, left), zeros around.
// A producer that writes its output straight into it (conv2d_into_padded)
// saves the consumer its padding pass (conv2d_from_padded reads it).
struct Conv2dPadded {
  Tensor data;  // [N·C·hp·wp]
  Shape shape;  // x's [N, C, H, W]
  std::uint32_t hp = 0, wp = 0;
  std::int32_t top = 0, left = 0;
  bool defined() const noexcept { return data.defined(); }
};
// For conv2d(x of shape x, weight, p): its padded input, zero-filled on
// `stream`, when the selected variant is blocked or depthwise; else undefined
// (no data).
Conv2dPadded conv2d_padded_input(Stream& stream, const Shape& x, const Shape& weight,
                                 const Conv2dParams& p);
// conv2d with y written into the interior of y (conv2d_padded_input of y's
// consumer; y.shape is conv2d's output shape). Blocked, depthwise and
// pointwise variants.
void conv2d_into_padded(Stream& stream, const Tensor& x, const Tensor& weight, const Tensor* bias,
                        const Conv2dPadded& y, const Conv2dParams& p,
                        const Conv2dPackedWeight* packed = nullptr,
                        const Tensor* residual = nullptr);
// conv2d of the input whose padded copy x is (conv2d_padded_input for these
// shapes and p, filled): no padding pass.
void conv2d_from_padded(Stream& stream, const Conv2dPadded& x, const Tensor& weight,
                        const Tensor* bias, const Tensor& y, const Conv2dParams& p,
                        const Conv2dPackedWeight* packed = nullptr,
                        const Tensor* residual = nullptr);

// The general form: x, y and the residual each plain (the tensor) or padded
// (io: x read from its padded copy (blocked, depthwise), y written into a
// padded tensor's interior (blocked, depthwise, pointwise), the residual read
// from a padded tensor: blocked, one in x's padded layout, for a stride-1
// 'same' convolution whose input is also its shortcut; pointwise, any padded
// tensor holding [N, Cr, H, W], such as the consumer's padded input of the
// previous sum in a chain of residual adds).
struct Conv2dPaddedIo {
  const Conv2dPadded* x = nullptr;
  const Conv2dPadded* y = nullptr;
  const Conv2dPadded* residual = nullptr;
};
void conv2d_padded(Stream& stream, const Tensor* x, const Tensor& weight, const Tensor* bias,
                   const Tensor* y, const Conv2dParams& p, const Conv2dPaddedIo& io,
                   const Conv2dPackedWeight* packed = nullptr, const Tensor* residual = nullptr);

// dx = ∂L/∂x given dy = ∂L/∂y (pre-activation gradient; see above). dx has x's
// shape [N, Cin, H, W] and is overwritten. p.algo: auto_select or direct (forces
// the gather kernel); blocked forces the transposed-forward path.
void conv2d_backward_data(Stream& stream, const Tensor& dy, const Tensor& weight, const Tensor& dx,
                          const Conv2dParams& p);

// dweight = ∂L/∂w [Cout, Cin/groups, KH, KW] and, when dbias is not nullptr,
// dbias = ∂L/∂b [Cout]; both overwritten. x is the forward input. groups == 1
// runs a blocked kernel (8 output channels × KW taps per invocation); p.algo ==
// direct forces one dw element per invocation (any groups).
void conv2d_backward_weight(Stream& stream, const Tensor& x, const Tensor& dy,
                            const Tensor& dweight, const Tensor* dbias, const Conv2dParams& p);

}  // namespace vkjr2::kernels
