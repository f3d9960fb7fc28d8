#include <vkjr2/kernels/ref/grid_sample_ref.hpp>
#include <vkjr2/kernels/ref/warp_ref.hpp>

#include <cstddef>

namespace vkjr2::ref {
namespace {

// Sampling positions x + dx, y + dy as N×H×W×2.
std::vector<double> flow_to_pixels(std::span<const float> flow, int n, int h, int w) {
  const std::size_t plane = std::size_t(h) * w;
  std::vector<double> pos(std::size_t(n) * plane * 2);
  for (int b = 0; b < n; ++b) {
    for (std::size_t p = 0; p < plane; ++p) {
      const std::size_t o = (b * plane + p) * 2;
      // In float, as the device computes it, so floor() agrees at cell edges.
      pos[o] = double(float(p % w) + flow[(2 * std::size_t(b)) * plane + p]);
      pos[o + 1] = double(float(p / w) +  // NOLINT(bugprone-integer-division): row index
                          flow[(2 * std::size_t(b) + 1) * plane + p]);
    }
  }
  return pos;
}

}  // namespace

std::vector<float> warp(std::span<const float> img, std::span<const float> flow, int n, int c,
                        int h, int w, kernels::SamplePadding padding) {
  return sample_pixels(img, flow_to_pixels(flow, n, h, w), {n, c, h, w, h, w}, padding);
}

void warp_backward(std::span<const float> img, std::span<const float> flow,
                   std::span<const float> d_out, int n, int c, int h, int w,
                   kernels::SamplePadding padding, std::vector<float>& d_img,
                   std::vector<float>& d_flow) {
  std::vector<double> d_pos;
  sample_pixels_backward(img, flow_to_pixels(flow, n, h, w), d_out, {n, c, h, w, h, w}, padding,
                         d_img, d_pos);
  const std::size_t plane = std::size_t(h) * w;
  d_flow.resize(std::size_t(n) * 2 * plane);
  for (int b = 0; b < n; ++b) {
    for (std::size_t p = 0; p < plane; ++p) {
      d_flow[2 * b * plane + p] = static_cast<float>(d_pos[(b * plane + p) * 2]);
      d_flow[(2 * b + 1) * plane + p] = static_cast<float>(d_pos[(b * plane + p) * 2 + 1]);
    }
  }
}

}  // namespace vkjr2::ref
