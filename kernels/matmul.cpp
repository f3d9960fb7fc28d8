#include <vkjr2/kernels/check.hpp>
#include <vkjr2/kernels/matmul.hpp>
#include <vkjr2/kernels/reduce.hpp>

#include <string>

namespace vkjr2::kernels {
namespace {

// shaders/matmul.comp's tile; kGroup: lanes per workgroup at most.
constexpr std::uint32_t kTileM = 4, kTileN = 8, kGroup = 64;

struct MatmulPush {
  std::uint32_t p_len, q_len, r_len;
  std::uint32_t a_sp, a_sr, b_sr, b_sq;
  std::uint32_t tiles_q;
  std::uint32_t has_bias;
};
static_assert(sizeof(MatmulPush) <= 128);

// C[P, Q] = A(p, r) · B(r, q) with the strides of MatmulPush.
void gemm(Stream& stream, const Tensor& a, const Tensor& b, const Tensor& c, const Tensor* bias,
          MatmulPush push) {
  static const KernelDef k{
      "matmul",
      {BindingKind::texel, BindingKind::texel, BindingKind::texel, BindingKind::storage},
      sizeof(MatmulPush)};
  push.tiles_q = div_up(push.q_len, kTileN);
  push.has_bias = bias != nullptr ? 1u : 0u;
  // The shader's TM and BVEC4: one row per tile for fewer than 4 rows; B as
  // vec4 texels when its rows are contiguous and every tile's 8 columns are
  // aligned and in range.
  const std::uint32_t tm = push.p_len < kTileM ? 1 : kTileM;
  const bool bvec4 = push.b_sq == 1 && push.b_sr % 4 == 0 && push.q_len % kTileN == 0;
  const std::uint64_t tiles = std::uint64_t(div_up(push.p_len, tm)) * push.tiles_q;
  // Fewer lanes per group when there are few tiles: a linear layer on one
  // row (the landmark net's fc, 17 tiles) had all of them in one group.
  const std::uint32_t lanes = group_lanes(tiles, stream.device().traits().min_workgroups, kGroup);
  stream.dispatch(k,
                  {texel(a), texel(b, bvec4 ? VK_FORMAT_R32G32B32A32_SFLOAT : VK_FORMAT_R32_SFLOAT),
                   texel(bias != nullptr ? *bias : a), out(c)},
                  push, groups_1d(div_up(tiles, lanes), stream.device().info()),
                  {lanes, tm, bvec4 ? 1u : 0u});
}

struct Dims {
  std::uint32_t m, k, n;
};

Dims check_x_w(const Tensor& x, const Tensor& w, const char* op) {
  require_f32_rank(x, 2, op, "x");
  require_f32_rank(w, 2, op, "w");
  if (x.shape()[1] != w.shape()[0]) {
    throw InvalidArgument(
        op, "inner dimensions differ: x " + x.shape().str() + " · w " + w.shape().str(),
        "x must be [M, K] and w [K, N]");
  }
  return {std::uint32_t(x.shape()[0]), std::uint32_t(x.shape()[1]), std::uint32_t(w.shape()[1])};
}

}  // namespace

void matmul(Stream& stream, const Tensor& x, const Tensor& w, const Tensor& y, const Tensor* bias) {
  const char* op = "matmul";
  const Dims d = check_x_w(x, w, op);
  require_f32(y, op, "y");
  require_shape(y, Shape{d.m, d.n}, op, "y");
  if (bias != nullptr) {
    require_f32(*bias, op, "bias");
    require_shape(*bias, Shape{d.n}, op, "bias");
  }
  gemm(stream, x, w, y, bias, MatmulPush{d.m, d.n, d.k, d.k, 1, d.n, 1, 0, 0});
}

void matmul_backward(Stream& stream, const Tensor& x, const Tensor& w, const Tensor& dy,
                     const Tensor* dx, const Tensor* dw, const Tensor* dbias) {
  const char* op = "matmul_backward";
  const Dims d = check_x_w(x, w, op);
  require_f32(dy, op, "dy");
  require_shape(dy, Shape{d.m, d.n}, op, "dy");
  if (dx != nullptr) {
    require_f32(*dx, op, "dx");
    require_shape(*dx, x.shape(), op, "dx");
    // dX[m, k] = Σ_n dY[m, n] W[k, n]
    gemm(stream, dy, w, *dx, nullptr, MatmulPush{d.m, d.k, d.n, d.n, 1, 1, d.n, 0, 0});
  }
  if (dw != nullptr) {
    require_f32(*dw, op, "dw");
    require_shape(*dw, w.shape(), op, "dw");
    // dW[k, n] = Σ_m X[m, k] dY[m, n]
    gemm(stream, x, dy, *dw, nullptr, MatmulPush{d.k, d.n, d.m, 1, d.k, d.n, 1, 0, 0});
  }
  if (dbias != nullptr) sum_channels(stream, dy, *dbias);
}

}  // namespace vkjr2::kernels
