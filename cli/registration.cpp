#include "registration.hpp"

#include <opencv2/core.hpp>
#include <opencv2/video/tracking.hpp>

#include <cstddef>

namespace vkjr2::cli {

DisRegistration dis_register(std::span<const float> grey, int frames, int height, int width) {
  const std::size_t plane = std::size_t(height) * std::size_t(width);
  DisRegistration r;
  r.mean.assign(plane, 0.f);
  for (int f = 0; f < frames; ++f) {
    for (std::size_t p = 0; p < plane; ++p) r.mean[p] += grey[std::size_t(f) * plane + p];
  }
  for (float& v : r.mean) v /= float(frames);
  cv::Mat mean8, frame8, flow;
  cv::Mat(height, width, CV_32F, r.mean.data()).convertTo(mean8, CV_8U, 255.0);
  const cv::Ptr<cv::DISOpticalFlow> dis =
      cv::DISOpticalFlow::create(cv::DISOpticalFlow::PRESET_MEDIUM);
  r.flow.resize(std::size_t(frames) * 2 * plane);
  for (int f = 0; f < frames; ++f) {
    // const_cast: cv::Mat wraps the pixels read-only here (convertTo reads).
    cv::Mat(height, width, CV_32F, const_cast<float*>(grey.data() + std::size_t(f) * plane))
        .convertTo(frame8, CV_8U, 255.0);
    dis->calc(mean8, frame8, flow);
    for (int y = 0; y < height; ++y) {
      const auto* row = flow.ptr<cv::Vec2f>(y);
      for (int x = 0; x < width; ++x) {
        r.flow[std::size_t(2 * f) * plane + std::size_t(y) * width + x] = row[x][0];
        r.flow[std::size_t(2 * f + 1) * plane + std::size_t(y) * width + x] = row[x][1];
      }
    }
  }
  return r;
}

int dis_threads() { return cv::getNumThreads(); }

jr2::TiltMeasure measure_tilt_dis(std::span<const float> grey, int frames, int height, int width,
                                  const jr2::TiltOptions& options) {
  jr2::check_grey_video(grey, frames, height, width, options);
  const DisRegistration r = dis_register(grey, frames, height, width);
  return jr2::tilt_statistics(r.flow, frames, height, width,
                              jr2::texture_map(r.mean, height, width, options.radius), options);
}

jr2::TurbulenceEstimate estimate_grey_video(const Device& device, std::span<const float> grey,
                                            int frames, int height, int width,
                                            const sim::Params& optics,
                                            const jr2::TurbulenceCalibration& calibration) {
  jr2::TiltMeasure tilt;
  if (calibration.uses_tilt()) {
    if (calibration.registration == "dis") {
      tilt = measure_tilt_dis(grey, frames, height, width, calibration.tilt);
    } else {
      Stream stream(device);
      tilt = jr2::measure_tilt(stream, Tensor::from(device, Shape{frames, 1, height, width}, grey),
                               calibration.tilt);
    }
  }
  jr2::SpectrumMeasure spectrum;
  if (calibration.uses_spectrum()) {
    spectrum = jr2::spectral_fluctuation(grey, frames, height, width, optics, calibration.spectrum);
  }
  return jr2::estimate_turbulence(tilt, spectrum, optics, calibration);
}

}  // namespace vkjr2::cli
