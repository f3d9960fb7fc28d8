// Internal to the kernels layer (not installed): what the convolution's
// plan, forward and backward share (the push constants, the shapes, the
// variant choice, the tiles and the padded geometry). Included as
// "internal/conv2d_impl.hpp" from kernels/conv2d*.cpp only.
#pragma once

#include <vkjr2/kernels/conv2d.hpp>
#include <vkjr2/runtime/kernel.hpp>

#include <cstdint>
#include <string>

namespace vkjr2::kernels::detail {

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

struct Dims {
  std::int64_t n, cin, h, w, cout, kh, kw, hout, wout;
};

std::string str(std::int64_t v);
// Validates x [N, Cin, H, W] and weight [Cout, Cin/groups, KH, KW] against p.
Dims dims_of(const char* op, const Shape& x, const Shape& w, const Conv2dParams& p);
ConvPush push_of(const Dims& d, const Conv2dParams& p);

// The blocked kernel's tile: each invocation computes 4·cg output channels ×
// ry rows × px consecutive pixels (cg·ry·px vec4 accumulators).
struct BlockedTile {
  std::uint32_t px = kPx, cg = 2, ry = 1;
  // Depthwise: extra zero columns left of the padding, so that the interior
  // (the producer's output) starts at a multiple of 4 and the pointwise conv
  // before it stores whole vec4 quads (the padded tensor's left = pad left + sh).
  std::uint32_t sh = 0;
};

// The tile of the blocked variant (conv2d_plan.cpp explains the choice).
BlockedTile blocked_tile(const ConvPush& c, const DeviceTraits& tr);
// The depthwise variant's tile.
BlockedTile depthwise_tile(const ConvPush& c, const DeviceTraits& tr);
// The tile of the variants that read a padded input (blocked, depthwise).
BlockedTile padded_tile(const ConvPush& c, Conv2dAlgo algo, const DeviceTraits& tr);
// Padded-input geometry for the blocked and depthwise kernels: every row read
// by a block of px × ry output pixels lies inside [hp, wp].
// sh: zero columns before the left padding (BlockedTile::sh).
void set_padded(ConvPush& c, std::uint32_t px = kPx, std::uint32_t ry = 1, std::uint32_t sh = 0);
void set_padded(ConvPush& c, const BlockedTile& t);
// Elements of the padded input the blocked or depthwise kernel reads.
std::uint64_t padded_elements(const Dims& d, const Conv2dParams& p, Conv2dAlgo algo,
                              const DeviceTraits& tr);
// The layout of the padded input the blocked or depthwise kernel reads.
PlaneLayout padded_layout(const Dims& d, const Conv2dParams& p, Conv2dAlgo algo,
                          const DeviceTraits& tr);

// The backward kernels differentiate conv(x), not conv(relu(x)).
void refuse_relu_input(const char* op, const Conv2dParams& p);
bool small_kernel(const Dims& d, const Conv2dParams& p);
// Empty string when `algo` can run these shapes, else why not.
std::string why_not(Conv2dAlgo algo, const Device& device, const Dims& d, const Conv2dParams& p);
// The one selection point: p.algo after checking it, else the first variant that runs.
Conv2dAlgo select(const Device& device, const Dims& d, const Conv2dParams& p, const char* op);

// OIHW (or, transposed, the [Cin][Cout] weight of the conv whose backward-data
// this is, flipped) → [Cout/8][Cin][KH][KW][8].
Tensor pack_weights(Stream& stream, const Tensor& weight, const ConvPush& c, bool transposed);
// Zero-padded copy of x for the blocked/depthwise kernels (c has set_padded()).
Tensor pad_input(Stream& stream, const Tensor& x, const ConvPush& c);

// The forward dispatch of one variant; c has everything but the padded
// geometry. prepacked: the weight already packed, else packed here.
// residual: [N, cres, Hout, Wout] added before the activation, or nullptr.
// x_padded (blocked, depthwise): x's padded copy already made (x is then its
// data); y_padded (blocked, depthwise, pointwise): the padded planes to write
// the output into (y is then their data); residual_padded (blocked: in x's
// padded layout; pointwise: any padded layout), read instead of residual.
void run_forward(Stream& stream, Conv2dAlgo algo, const Tensor& x, const Tensor& weight,
                 const Tensor* bias, const Tensor& y, ConvPush c, bool transposed_weight,
                 const Tensor* prepacked = nullptr, const Tensor* residual = nullptr,
                 const Planes* x_padded = nullptr, const Planes* y_padded = nullptr,
                 const Planes* residual_padded = nullptr);

}  // namespace vkjr2::kernels::detail
