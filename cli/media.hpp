// Reading and writing the media the CLI accepts: images (PNG, JPEG, TIFF incl.
// 16-bit, anything OpenCV's imgcodecs reads), .npy float32 HWC RGB arrays in
// 0..255, videos (anything OpenCV's FFmpeg backend reads) and folders of these.
#pragma once

#include <vkjr2/nets/host_tensor.hpp>

#include <filesystem>
#include <functional>
#include <memory>
#include <string>
#include <vector>

namespace vkjr2::cli {

// An RGB image as H×W×3 float32 in 0..255 (16-bit inputs are scaled by
// 255/65535, grey ones expanded to RGB, alpha dropped).
using Image = nets::HostTensor;

bool is_image_path(const std::filesystem::path& path);  // by extension (incl. .npy)
bool is_video_path(const std::filesystem::path& path);

// Throws vkjr2::Error naming the file and what to do when it cannot be read.
Image read_image(const std::filesystem::path& path);

// Calls `frame(index, image)` for every `stride`-th frame (at most max_frames;
// 0 = all); returns the frame count read. Throws when the file cannot be opened.
std::size_t read_video(const std::filesystem::path& path, std::size_t stride,
                       std::size_t max_frames,
                       const std::function<void(std::size_t, const Image&)>& frame);

// PNG (8-bit) written atomically: temporary name in the same folder, then
// rename. Refuses to replace an existing file unless `force`.
void write_png(const std::filesystem::path& path, const Image& image, bool force);

// Frames per second a video declares (0 when it declares none).
double video_fps(const std::filesystem::path& path);

// A video written atomically: frames go to a temporary file beside `path`
// (same extension, so OpenCV picks the same container), finish() renames it
// into place; a writer destroyed before finish() removes its temporary file.
// .avi is Motion-JPEG, .mp4/.mov/.mkv MPEG-4 part 2 (what OpenCV's FFmpeg
// backend writes without extra codecs).
class VideoWriter {
 public:
  VideoWriter(std::filesystem::path path, double fps, int width, int height, bool force);
  ~VideoWriter();
  VideoWriter(const VideoWriter&) = delete;
  VideoWriter& operator=(const VideoWriter&) = delete;
  void write(const Image& frame);  // H×W×3 RGB 0..255, the size given
  void finish();
  std::size_t frames() const { return frames_; }

 private:
  struct State;
  std::filesystem::path path_, tmp_;
  std::unique_ptr<State> state_;
  int width_, height_;
  std::size_t frames_ = 0;
  bool finished_ = false;
};

// The regular files directly inside `dir` that `keep` accepts, sorted by name.
std::vector<std::filesystem::path> list_files(
    const std::filesystem::path& dir,
    const std::function<bool(const std::filesystem::path&)>& keep);
// Images directly inside `dir`, sorted by name.
std::vector<std::filesystem::path> list_images(const std::filesystem::path& dir);

// Throws a clear error when `path` exists and `force` is false.
void check_writable(const std::filesystem::path& path, bool force);

}  // namespace vkjr2::cli
