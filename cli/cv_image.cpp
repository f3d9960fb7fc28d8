#include "cv_image.hpp"

#include <vkjr2/runtime/error.hpp>

#include <opencv2/imgproc.hpp>

namespace vkjr2::cli {

vkjr2::HostTensor image_from_bgr(const cv::Mat& bgr) {
  cv::Mat rgb, f;
  cv::cvtColor(bgr, rgb, cv::COLOR_BGR2RGB);
  rgb.convertTo(f, CV_32FC3);
  vkjr2::HostTensor img;
  img.shape = {f.rows, f.cols, 3};
  img.values.assign(reinterpret_cast<const float*>(f.datastart),
                    reinterpret_cast<const float*>(f.dataend));
  return img;
}

cv::Mat image_to_bgr(const vkjr2::HostTensor& img) {
  if (img.shape.size() != 3 || img.shape[2] != 3 ||
      std::int64_t(img.values.size()) != img.shape[0] * img.shape[1] * 3) {
    throw InvalidArgument("image_to_bgr", "image has shape " + vkjr2::shape_str(img.shape),
                          "pass an H×W×3 RGB image");
  }
  const cv::Mat rgb(int(img.shape[0]), int(img.shape[1]), CV_32FC3,
                    const_cast<float*>(img.values.data()));  // NOLINT: read only
  cv::Mat bgr, out;
  cv::cvtColor(rgb, bgr, cv::COLOR_RGB2BGR);
  bgr.convertTo(out, CV_8UC3);  // saturating round
  return out;
}

}  // namespace vkjr2::cli
