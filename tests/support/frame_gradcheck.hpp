// Finite-difference check of sim::Simulator::frame_backward. For fixed
// turbulence the frame is linear in x, so L = Σ w ⊙ frame(x) is checked by
// central differences, re-simulating with the same seed each time.
#pragma once

#include <vkjr2/sim/simulator.hpp>

#include <cstdint>
#include <span>
#include <string>
#include <vector>

#include "support/gradcheck.hpp"
#include "support/test_device.hpp"

namespace vkjr2::test {

// x: one frame of sim's image shape; w: random weights from weight_seed.
inline void expect_frame_gradient(sim::Simulator& sim, const std::vector<float>& xs,
                                  std::uint32_t weight_seed, std::uint64_t turbulence_seed,
                                  const std::string& what) {
  Device& dev = device();
  const sim::ImageShape& im = sim.params().image;
  const Shape shape{im.batch, im.channels, im.height, im.width};
  const auto w = random_floats(std::size_t(shape.numel()), weight_seed);
  auto loss = [&](std::span<const float> xv) {
    Tensor x = Tensor::from(dev, shape, xv);
    Tensor y = Tensor::empty(dev, shape);
    sim.reset(turbulence_seed);
    Stream s(dev);
    sim.frame(s, x, y);
    s.run();
    const auto yv = y.download();
    double l = 0;
    for (std::size_t i = 0; i < yv.size(); ++i) l += double(w[i]) * yv[i];
    return l;
  };
  Tensor x = Tensor::from(dev, shape, xs);
  Tensor y = Tensor::empty(dev, shape), dy = Tensor::from(dev, shape, w),
         dx = Tensor::empty(dev, shape);
  sim.reset(turbulence_seed);
  Stream s(dev);
  sim.frame(s, x, y);
  sim.frame_backward(s, dy, dx);
  s.run();
  expect_gradient_matches(loss, xs, dx.download(), what);
}

}  // namespace vkjr2::test
