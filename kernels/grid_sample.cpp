#include <vkjr2/kernels/check.hpp>
#include <vkjr2/kernels/grid_sample.hpp>

#include <string>

#include "internal/sample.hpp"

namespace vkjr2::kernels {
namespace {

constexpr std::uint32_t kAffineGroup = 256;  // affine_grid*.comp local size

// Mirrors the push blocks of shaders/affine_grid*.comp.
struct AffinePush {
  std::uint32_t n_batch, h, w, align_corners;
};
static_assert(sizeof(AffinePush) <= 128);

detail::SampleGeometry grid_geometry(const Tensor& input, const Tensor& grid,
                                     const GridSampleOptions& options, const char* op) {
  require_f32_rank(input, 4, op, "input");
  require_f32_rank(grid, 4, op, "grid");
  const Shape& s = input.shape();
  const Shape& gs = grid.shape();
  if (gs[0] != s[0] || gs[3] != 2) {
    throw InvalidArgument(op, "grid has shape " + gs.str() + ", expected [" + std::to_string(s[0]) +
                                  ", Hout, Wout, 2] for input " + s.str());
  }
  detail::SampleGeometry g;
  g.n_batch = static_cast<std::uint32_t>(s[0]);
  g.channels = static_cast<std::uint32_t>(s[1]);
  g.in_h = static_cast<std::uint32_t>(s[2]);
  g.in_w = static_cast<std::uint32_t>(s[3]);
  g.out_h = static_cast<std::uint32_t>(gs[1]);
  g.out_w = static_cast<std::uint32_t>(gs[2]);
  g.grid_mode = true;
  g.padding = options.padding;
  g.align_corners = options.align_corners;
  return g;
}

Shape out_shape(const detail::SampleGeometry& g) {
  return Shape{g.n_batch, g.channels, g.out_h, g.out_w};
}

// theta N×2×3 and grid N×H×W×2 agree; returns the push constants.
AffinePush affine_push(const Tensor& theta, const Tensor& grid, bool align_corners, const char* op,
                       const char* theta_name, const char* grid_name) {
  require_f32_rank(theta, 3, op, theta_name);
  require_f32_rank(grid, 4, op, grid_name);
  const Shape& gs = grid.shape();
  require_shape(theta, Shape{gs[0], 2, 3}, op, theta_name);
  if (gs[3] != 2) {
    throw InvalidArgument(
        op, std::string(grid_name) + " has shape " + gs.str() + ", expected [N, H, W, 2]");
  }
  return {static_cast<std::uint32_t>(gs[0]), static_cast<std::uint32_t>(gs[1]),
          static_cast<std::uint32_t>(gs[2]), align_corners ? 1u : 0u};
}

}  // namespace

void grid_sample(Stream& stream, const Tensor& input, const Tensor& grid, const Tensor& out,
                 GridSampleOptions options) {
  const detail::SampleGeometry g = grid_geometry(input, grid, options, "grid_sample");
  require_f32(out, "grid_sample", "out");
  require_shape(out, out_shape(g), "grid_sample", "out");
  detail::sample_forward(stream, g, input, grid, out);
}

void grid_sample_backward(Stream& stream, const Tensor& input, const Tensor& grid,
                          const Tensor& d_out, const Tensor* d_input, const Tensor* d_grid,
                          GridSampleOptions options) {
  const char* op = "grid_sample_backward";
  const detail::SampleGeometry g = grid_geometry(input, grid, options, op);
  require_f32(d_out, op, "d_out");
  require_shape(d_out, out_shape(g), op, "d_out");
  if (!d_input && !d_grid) {
    throw InvalidArgument(op, "both d_input and d_grid are null", "pass at least one of them");
  }
  if (d_input) {
    require_f32(*d_input, op, "d_input");
    require_same_shape(input, *d_input, op, "input", "d_input");
    if (d_input->numel() >= (std::int64_t(1) << 31)) {
      throw InvalidArgument(op, "d_input " + d_input->shape().str() + " has 2^31 or more elements",
                            "split the batch");
    }
  }
  if (d_grid) {
    require_f32(*d_grid, op, "d_grid");
    require_same_shape(grid, *d_grid, op, "grid", "d_grid");
  }
  detail::sample_backward(stream, g, input, grid, d_out, d_input, d_grid);
}

void affine_grid(Stream& stream, const Tensor& theta, const Tensor& grid, bool align_corners) {
  static const KernelDef kAffine{
      "affine_grid", {BindingKind::texel, BindingKind::storage}, sizeof(AffinePush)};
  const AffinePush push = affine_push(theta, grid, align_corners, "affine_grid", "theta", "grid");
  const std::uint64_t pixels = std::uint64_t(push.n_batch) * push.h * push.w;
  stream.dispatch(kAffine, {texel(theta), out(grid)}, push,
                  groups_1d(div_up(pixels, kAffineGroup), stream.device().info()));
}

void affine_grid_backward(Stream& stream, const Tensor& d_grid, const Tensor& d_theta,
                          bool align_corners) {
  static const KernelDef kAffineBackward{
      "affine_grid_backward", {BindingKind::texel, BindingKind::storage}, sizeof(AffinePush)};
  const AffinePush push =
      affine_push(d_theta, d_grid, align_corners, "affine_grid_backward", "d_theta", "d_grid");
  stream.dispatch(kAffineBackward, {texel(d_grid, VK_FORMAT_R32G32_SFLOAT), out(d_theta)}, push,
                  groups_1d(push.n_batch, stream.device().info()));
}

}  // namespace vkjr2::kernels
