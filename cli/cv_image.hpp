// OpenCV matrices ↔ the H×W×3 RGB float images (0..255) the commands pass
// around: the one conversion for decoded pictures, drawn panels, plots and
// written frames.
#pragma once

#include <vkjr2/runtime/host_tensor.hpp>

#include <opencv2/core.hpp>

namespace vkjr2::cli {

// An 8-bit BGR matrix → an H×W×3 RGB float image.
vkjr2::HostTensor image_from_bgr(const cv::Mat& bgr);
// An H×W×3 RGB float image → an 8-bit BGR matrix (rounded, saturated to
// 0..255). Throws InvalidArgument for another shape.
cv::Mat image_to_bgr(const vkjr2::HostTensor& rgb);

}  // namespace vkjr2::cli
