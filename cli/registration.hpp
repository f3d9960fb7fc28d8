// Dense registration of grey video frames against their mean by OpenCV's DIS
// optical flow: what `vkjr2 estimate` measures the tilt with, and what
// `vkjr2 bench estimate` times as the peer of the device kernel.
#pragma once

#include <span>
#include <vector>

namespace vkjr2::cli {

struct DisRegistration {
  std::vector<float> mean;  // H×W, 0..1: the frames' mean
  std::vector<float> flow;  // T×2×H×W planar: frame t moved by flow_t registers onto the mean
};

// grey: T×H×W in 0..1. DIS (medium preset) of every frame against the 8-bit
// mean.
DisRegistration dis_register(std::span<const float> grey, int frames, int height, int width);
// The threads OpenCV runs it on.
int dis_threads();

}  // namespace vkjr2::cli
