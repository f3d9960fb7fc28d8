// 2-D convolution (cross-correlation, as in PyTorch/TF): forward with bias and
// fused activation, backward-data (dX) and backward-weight (dW, dbias).
//
// Layouts (f32, contiguous):
//   x      [N, Cin, H, W]                 (NCHW)
//   weight [Cout, Cin/groups, KH, KW]     (OIHW, as PyTorch). TF.js/Keras HWIO
//          weights must be repacked to OIHW by the caller once at load time.
//          The blocked and pointwise variants read weights repacked to
//          [ceil(Cout/8)][Cin][KH][KW][8]: conv2d() packs them on every call;
//          a Conv2dPlan packs them once (again after the weight changed).
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
// Variants (chosen in one place, when a Conv2dPlan is made; all tested):
//   direct     any parameters; one output per invocation (slow fallback).
//   blocked    groups == 1, KH, KW <= 7, stride_x, dilation_x <= 4: a tile of
//              4 or 8 output channels × 1..25 rows × up to 20 pixels per
//              invocation, chosen per shape (a row of up to 20 pixels is one
//              block, so small planes waste no lanes); the input is read
//              zero-padded (Conv2dPlan::input_layout: its producer writes it
//              so, else one cheap padding pass) as vec4 texels, weights packed
//              to [Cout/8][Cin][KH][KW][8] (per call, or once by a plan) and
//              read as vec4 texels; KH/KW/stride_x/
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
// The layout choices (variant, tile, padded input geometry) come from the
// device's DeviceTraits. Temporaries (padded input, packed weights) come from
// Tensor::empty and are kept alive by the Stream.
#pragma once

#include <vkjr2/kernels/planes.hpp>
#include <vkjr2/runtime/stream.hpp>

#include <cstdint>
#include <string>

namespace vkjr2::kernels {

enum class Activation : std::uint8_t { none, relu, leaky_relu };

enum class Conv2dAlgo : std::uint8_t {
  auto_select,  // the plan picks
  direct,
  blocked,
  pointwise,
  depthwise,
};
const char* conv2d_algo_name(Conv2dAlgo algo) noexcept;

struct Padding2d {
  int top = 0, bottom = 0, left = 0, right = 0;
  bool operator==(const Padding2d&) const = default;
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
  bool operator==(const Conv2dParams&) const = default;
};

// TF "SAME" padding for one axis: total = max((ceil(in/s) − 1)·s + (k−1)·d + 1 − in, 0),
// before = total / 2, after = total − before (the extra pixel goes after).
Padding2d same_padding(std::int64_t in_h, std::int64_t in_w, int kh, int kw, int stride_y,
                       int stride_x, int dilation_y = 1, int dilation_x = 1);

// [N, Cout, Hout, Wout] for x [N, Cin, H, W] and weight [Cout, Cin/groups, KH, KW];
// throws InvalidArgument for inconsistent shapes or parameters.
Shape conv2d_output_shape(const Shape& x, const Shape& weight, const Conv2dParams& p);

// One convolution's choices for one input shape on one device, made once:
// the variant (p.algo when not auto_select, after checking it can run these
// shapes; else InvalidArgument), its tile and so the layout it reads x in,
// and, once pack() ran, the weight in the layout the variant reads.
class Conv2dPlan {
 public:
  Conv2dPlan() = default;  // no plan (defined() is false)
  // For x [N, Cin, H, W], weight [Cout, Cin/groups, KH, KW] and p; throws
  // InvalidArgument for inconsistent shapes or parameters.
  Conv2dPlan(const Device& device, const Shape& x, const Shape& weight, const Conv2dParams& p);

  bool defined() const noexcept { return device_ != nullptr; }
  // Whether the plan was made for `device` (any handle to the same one).
  bool made_for(const Device& device) const noexcept {
    return device_ != nullptr && device.shared_core().get() == device_;
  }
  Conv2dAlgo algo() const noexcept { return algo_; }
  const Shape& input_shape() const noexcept { return x_; }
  const Shape& weight_shape() const noexcept { return weight_; }
  const Shape& output_shape() const noexcept { return y_; }
  const Conv2dParams& params() const noexcept { return p_; }

  // The layout run() reads x in with no padding pass: padded planes for the
  // blocked and depthwise variants, else plain. A producer that writes x
  // into Planes::make(stream, x, input_layout()) saves the padding pass.
  const PlaneLayout& input_layout() const noexcept { return input_layout_; }
  // Whether run() writes y into padded planes (blocked, depthwise,
  // pointwise; the others write plain y only).
  bool writes_padded() const noexcept;
  // Empty when run() takes r as the residual, else why not. Plain residuals
  // [N, 1..Cout, Hout, Wout] always; padded ones: the pointwise variant in
  // any layout, the blocked one in input_layout() when y has x's size (a
  // stride-1 'same' convolution whose input is also its shortcut).
  std::string residual_misfit(const Planes& r) const;

  // Whether the variant reads a packed weight (blocked, pointwise).
  bool reads_packed_weight() const noexcept;
  // Packs weight (weight_shape()) for the variant, recorded on `stream`; the
  // plan keeps it and run() reads it from then on. It is a copy: after the
  // weight changes (an optimizer step, a load), pack again. Nothing to do
  // for the variants that read the weight as it is.
  void pack(Stream& stream, const Tensor& weight);
  bool packed() const noexcept { return packed_.defined(); }

  // y = act(conv(x, weight) + bias + residual). x: plain, or padded in
  // input_layout(); y: plain, or padded planes when writes_padded() (any
  // layout holding the output); bias may be nullptr; residual: nullptr or
  // one residual_misfit() accepts. The weight is read packed when pack() ran
  // (weight must then be the tensor it packed, unchanged), else packed here.
  void run(Stream& stream, const Planes& x, const Tensor& weight, const Tensor* bias,
           const Planes& y, const Planes* residual = nullptr) const;

 private:
  const void* device_ = nullptr;  // the device's core (identity only)
  Shape x_, weight_, y_;
  Conv2dParams p_;
  Conv2dAlgo algo_ = Conv2dAlgo::auto_select;
  PlaneLayout input_layout_;
  Tensor packed_;
};

// y = act(conv(x, weight) + bias + residual) with a plan made for this call
// (weights packed per call when the variant reads them packed). bias may be
// nullptr. residual: [N, Cr, Hout, Wout] with 1 <= Cr <= Cout, a tensor
// other than y, or nullptr (every variant takes it: a residual block's add
// and ReLU in the conv's epilogue). Its gradient is the pre-activation dy
// (channels < Cr).
void conv2d(Stream& stream, const Tensor& x, const Tensor& weight, const Tensor* bias,
            const Tensor& y, const Conv2dParams& p, const Tensor* residual = nullptr);

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
