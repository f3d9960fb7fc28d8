// Dense registration of grey video frames against their mean by OpenCV's DIS
// optical flow: what `vkjr2 estimate` measures the tilt with, and what
// `vkjr2 bench estimate` times as the peer of the device kernel; and the
// turbulence estimate of a grey video as the command runner makes it.
#pragma once

#include <vkjr2/jr2/turbulence.hpp>
#include <vkjr2/runtime/device.hpp>
#include <vkjr2/sim/params.hpp>

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

// The tilt of grey frames (T×H×W, 0..1) by DIS against their mean
// (jr2::tilt_statistics with the options' texture threshold and border).
jr2::TiltMeasure measure_tilt_dis(std::span<const float> grey, int frames, int height, int width,
                                  const jr2::TiltOptions& options);

// The estimate of grey frames (T×H×W, 0..1) with the cues the calibration
// uses: the tilt by its registration ("dis" here, "lk" on `device`) and the
// spectral fluctuation. Throws InvalidArgument for a video it cannot measure.
jr2::TurbulenceEstimate estimate_grey_video(const Device& device, std::span<const float> grey,
                                            int frames, int height, int width,
                                            const sim::Params& optics,
                                            const jr2::TurbulenceCalibration& calibration);

}  // namespace vkjr2::cli
