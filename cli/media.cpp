#include "media.hpp"

#include <vkjr2/nets/npy.hpp>
#include <vkjr2/runtime/error.hpp>

#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <opencv2/videoio.hpp>
#include <unistd.h>

#include <algorithm>
#include <cctype>
#include <cmath>
#include <functional>
#include <system_error>

#include "log.hpp"

namespace vkjr2::cli {
namespace {

std::string lower_ext(const std::filesystem::path& p) {
  std::string e = p.extension().string();
  std::transform(e.begin(), e.end(), e.begin(),
                 [](unsigned char c) { return char(std::tolower(c)); });
  return e;
}

Image from_mat(const cv::Mat& m, const std::string& source) {
  cv::Mat rgb;
  switch (m.channels()) {
    case 1:
      cv::cvtColor(m, rgb, cv::COLOR_GRAY2RGB);
      break;
    case 3:
      cv::cvtColor(m, rgb, cv::COLOR_BGR2RGB);
      break;
    case 4:
      cv::cvtColor(m, rgb, cv::COLOR_BGRA2RGB);
      break;
    default:
      throw Error("read_image", source + " has " + std::to_string(m.channels()) + " channels",
                  "pass a grey, RGB or RGBA image");
  }
  double scale = 1.0;
  switch (rgb.depth()) {
    case CV_8U:
      break;
    case CV_16U:
      scale = 255.0 / 65535.0;
      break;
    case CV_32F:
      break;  // taken as 0..255 already
    default:
      throw Error("read_image", source + " has an unsupported sample type",
                  "pass 8-bit or 16-bit images (or float32 .npy arrays)");
  }
  cv::Mat f;
  rgb.convertTo(f, CV_32FC3, scale);
  Image img;
  img.shape = {f.rows, f.cols, 3};
  img.values.resize(std::size_t(f.rows) * std::size_t(f.cols) * 3);
  for (int r = 0; r < f.rows; ++r) {
    const float* row = f.ptr<float>(r);
    std::copy(row, row + std::size_t(f.cols) * 3,
              img.values.begin() + std::ptrdiff_t(r) * f.cols * 3);
  }
  return img;
}

}  // namespace

bool is_image_path(const std::filesystem::path& path) {
  static const char* kExt[] = {".png", ".jpg", ".jpeg", ".tif", ".tiff", ".bmp", ".webp", ".npy"};
  const std::string e = lower_ext(path);
  return std::any_of(std::begin(kExt), std::end(kExt), [&](const char* k) { return e == k; });
}

bool is_video_path(const std::filesystem::path& path) {
  static const char* kExt[] = {".avi", ".mp4", ".mkv", ".mov", ".webm", ".m4v", ".mpg", ".mpeg"};
  const std::string e = lower_ext(path);
  return std::any_of(std::begin(kExt), std::end(kExt), [&](const char* k) { return e == k; });
}

Image read_image(const std::filesystem::path& path) {
  const std::string source = path.string();
  if (!std::filesystem::exists(path)) {
    throw Error("read_image", source + " does not exist", "check the path");
  }
  if (lower_ext(path) == ".npy") {
    Image img = nets::read_npy(path);
    if (img.shape.size() == 4 && img.shape[0] == 1) img.shape.erase(img.shape.begin());
    if (img.shape.size() != 3 || img.shape[2] != 3 || img.shape[0] <= 0 || img.shape[1] <= 0) {
      throw Error("read_image", source + " has shape " + nets::shape_str(img.shape),
                  "save images as float32 arrays of shape (height, width, 3), RGB in 0..255");
    }
    for (float v : img.values) {
      if (!std::isfinite(v)) {
        throw Error("read_image", source + " contains NaN or infinite values",
                    "save finite pixel values in 0..255");
      }
    }
    return img;
  }
  cv::Mat m = cv::imread(source, cv::IMREAD_UNCHANGED);
  if (m.empty()) {
    throw Error("read_image", "cannot decode " + source + " as an image",
                "pass a PNG, JPEG or TIFF file (or a float32 .npy array); the file may be "
                "truncated or corrupt");
  }
  return from_mat(m, source);
}

std::size_t read_video(const std::filesystem::path& path, std::size_t stride,
                       std::size_t max_frames,
                       const std::function<void(std::size_t, const Image&)>& frame) {
  const std::string source = path.string();
  if (!std::filesystem::exists(path))
    throw Error("read_video", source + " does not exist", "check the path");
  cv::VideoCapture cap(source, cv::CAP_FFMPEG);
  if (!cap.isOpened()) {
    throw Error("read_video", "cannot open " + source + " as a video",
                "pass a video OpenCV's FFmpeg backend reads (e.g. .avi, .mp4)");
  }
  stride = std::max<std::size_t>(stride, 1);
  std::size_t index = 0, used = 0;
  cv::Mat m;
  while (cap.read(m)) {
    if (index % stride == 0) {
      frame(index, from_mat(m, source + " frame " + std::to_string(index)));
      if (++used == max_frames) break;
    }
    ++index;
  }
  if (index == 0) {
    throw Error("read_video", source + " holds no decodable frame",
                "the file may be truncated or use a codec FFmpeg cannot decode");
  }
  return used;
}

void check_writable(const std::filesystem::path& path, bool force) {
  if (!force && std::filesystem::exists(path)) {
    throw Error("write", path.string() + " already exists", "pass --force to replace it");
  }
}

void write_png(const std::filesystem::path& path, const Image& image, bool force) {
  check_writable(path, force);
  if (image.shape.size() != 3 || image.shape[2] != 3) {
    throw InvalidArgument("write_png", "image has shape " + nets::shape_str(image.shape),
                          "pass an H×W×3 RGB image");
  }
  const int h = int(image.shape[0]), w = int(image.shape[1]);
  cv::Mat rgb(h, w, CV_32FC3, const_cast<float*>(image.values.data()));  // NOLINT: read only
  cv::Mat bgr, out;
  cv::cvtColor(rgb, bgr, cv::COLOR_RGB2BGR);
  bgr.convertTo(out, CV_8UC3);  // saturating round
  const auto tmp = path.parent_path() /
                   (path.filename().string() + ".tmp-" + std::to_string(::getpid()) + ".png");
  bool ok = false;
  try {
    ok = cv::imwrite(tmp.string(), out);
  } catch (const cv::Exception&) {
    ok = false;
  }
  if (!ok) {
    std::error_code ec;
    std::filesystem::remove(tmp, ec);
    throw Error("write_png", "cannot write " + path.string(),
                "check that the folder exists and is writable");
  }
  std::filesystem::rename(tmp, path);
  log_info("wrote " + path.string() + " (" + std::to_string(image.shape[1]) + "x" +
           std::to_string(image.shape[0]) + ")");
}

double video_fps(const std::filesystem::path& path) {
  cv::VideoCapture cap(path.string(), cv::CAP_FFMPEG);
  const double fps = cap.isOpened() ? cap.get(cv::CAP_PROP_FPS) : 0.0;
  return std::isfinite(fps) && fps > 0 ? fps : 0.0;
}

struct VideoWriter::State {
  cv::VideoWriter writer;
};

VideoWriter::VideoWriter(std::filesystem::path path, double fps, int width, int height, bool force)
    : path_(std::move(path)), state_(std::make_unique<State>()), width_(width), height_(height) {
  check_writable(path_, force);
  const std::string ext = lower_ext(path_);
  int fourcc = 0;
  if (ext == ".avi") {
    fourcc = cv::VideoWriter::fourcc('M', 'J', 'P', 'G');
  } else if (ext == ".mp4" || ext == ".mov" || ext == ".mkv") {
    fourcc = cv::VideoWriter::fourcc('m', 'p', '4', 'v');
  } else {
    throw InvalidArgument("write_video", path_.string() + ": unknown video extension '" + ext + "'",
                          "use .avi (Motion-JPEG) or .mp4");
  }
  tmp_ = path_.parent_path() / (path_.stem().string() + ".tmp-" + std::to_string(::getpid()) + ext);
  bool ok = false;
  try {
    ok = state_->writer.open(tmp_.string(), cv::CAP_FFMPEG, fourcc, fps > 0 ? fps : 25.0,
                             cv::Size(width, height));
  } catch (const cv::Exception&) {
    ok = false;
  }
  if (!ok) {
    std::error_code ec;
    std::filesystem::remove(tmp_, ec);
    throw Error("write_video", "cannot write " + path_.string(),
                "check that the folder exists and is writable");
  }
}

VideoWriter::~VideoWriter() {
  if (!finished_) {
    state_->writer.release();
    std::error_code ec;
    std::filesystem::remove(tmp_, ec);
  }
}

void VideoWriter::write(const Image& frame) {
  if (frame.shape.size() != 3 || frame.shape[0] != height_ || frame.shape[1] != width_ ||
      frame.shape[2] != 3) {
    throw InvalidArgument("write_video", "frame has shape " + nets::shape_str(frame.shape) +
                                             ", the video is " + std::to_string(height_) + "×" +
                                             std::to_string(width_) + "×3");
  }
  cv::Mat rgb(height_, width_, CV_32FC3,
              const_cast<float*>(frame.values.data()));  // NOLINT: read only
  cv::Mat bgr, out;
  cv::cvtColor(rgb, bgr, cv::COLOR_RGB2BGR);
  bgr.convertTo(out, CV_8UC3);
  state_->writer.write(out);
  ++frames_;
}

void VideoWriter::finish() {
  if (finished_) return;
  state_->writer.release();
  if (frames_ == 0) {
    throw Error("write_video", "no frame was written to " + path_.string(), "check the input");
  }
  std::filesystem::rename(tmp_, path_);
  finished_ = true;
  log_info("wrote " + path_.string() + " (" + std::to_string(frames_) + " frames)");
}

std::vector<std::filesystem::path> list_files(
    const std::filesystem::path& dir,
    const std::function<bool(const std::filesystem::path&)>& keep) {
  std::vector<std::filesystem::path> out;
  for (const auto& e : std::filesystem::directory_iterator(dir)) {
    if (e.is_regular_file() && keep(e.path())) out.push_back(e.path());
  }
  std::sort(out.begin(), out.end());
  return out;
}

std::vector<std::filesystem::path> list_images(const std::filesystem::path& dir) {
  return list_files(dir, [](const std::filesystem::path& p) { return is_image_path(p); });
}

}  // namespace vkjr2::cli
