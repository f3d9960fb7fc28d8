#include "clips.hpp"

#include <opencv2/core.hpp>
#include <opencv2/imgproc.hpp>

#include <algorithm>
#include <cmath>

namespace vkjr2::cli {

vkjr2::HostTensor face_clip(const vkjr2::HostTensor& img, const nets::FaceBox& box, int clip_size,
                            int face_px) {
  const int h = int(img.shape[0]), w = int(img.shape[1]);
  cv::Mat src(h, w, CV_32FC3, const_cast<float*>(img.values.data()));  // NOLINT
  const double s = double(face_px) / std::max(box.width, 1.0);
  const double cx = (box.x + box.width / 2) * s, cy = (box.y + box.height / 2) * s;
  cv::Mat scaled;
  cv::resize(src, scaled,
             cv::Size(std::max(1, int(std::lround(w * s))), std::max(1, int(std::lround(h * s)))),
             0, 0, s < 1 ? cv::INTER_AREA : cv::INTER_CUBIC);
  const int x0 = int(std::lround(cx - clip_size / 2.0)),
            y0 = int(std::lround(cy - clip_size / 2.0));
  const int left = std::max(0, -x0), top = std::max(0, -y0);
  const int right = std::max(0, x0 + clip_size - scaled.cols);
  const int bottom = std::max(0, y0 + clip_size - scaled.rows);
  cv::Mat padded;
  cv::copyMakeBorder(scaled, padded, top, bottom, left, right, cv::BORDER_REPLICATE);
  cv::Mat clip = padded(cv::Rect(x0 + left, y0 + top, clip_size, clip_size)).clone();
  cv::min(cv::max(clip, 0.0), 255.0, clip);
  vkjr2::HostTensor out;
  out.shape = {clip_size, clip_size, 3};
  out.values.assign(reinterpret_cast<const float*>(clip.datastart),
                    reinterpret_cast<const float*>(clip.dataend));
  return out;
}

}  // namespace vkjr2::cli
