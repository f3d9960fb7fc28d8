// Reading and writing the media the CLI accepts: images (PNG, JPEG, TIFF incl.
// 16-bit, BMP, WebP: what OpenCV's imgcodecs reads), .npy float32 arrays in
// 0..255 (H×W×3 RGB, H×W×1 or H×W grey), videos (anything OpenCV's FFmpeg
// backend reads) and folders of these.
//
// A truncated or corrupt file is an error, never a half-grey picture; an image
// larger than kMaxImageSide² is refused from its header, before it is decoded.
// The decoders' own messages (libpng, libjpeg, FFmpeg, OpenCV's log) are kept
// off the terminal unless --verbose.
#pragma once

#include <vkjr2/runtime/device.hpp>
#include <vkjr2/runtime/host_tensor.hpp>

#include <cstdint>
#include <filesystem>
#include <functional>
#include <initializer_list>
#include <memory>
#include <string>
#include <vector>

#include "probe_run.hpp"

namespace vkjr2::cli {

// An RGB image as H×W×3 float32 in 0..255 (16-bit inputs are scaled by
// 255/65535, grey ones expanded to RGB, alpha dropped).
using Image = vkjr2::HostTensor;

bool is_image_path(const std::filesystem::path& path);  // by extension (incl. .npy)
bool is_video_path(const std::filesystem::path& path);

// The largest image side and pixel count any command reads (16.8 MP: a
// 4096×4096 RGB frame is 192 MiB as float32 on the host).
constexpr std::int64_t kMaxImageSide = 4096;
constexpr std::int64_t kMaxImagePixels = kMaxImageSide * kMaxImageSide;

// Throws vkjr2::Error naming the file and what to do when it cannot be read.
Image read_image(const std::filesystem::path& path);

// Width and height an image file declares in its header (PNG, JPEG, BMP; 0×0
// for other formats, whose size is known only once decoded).
struct ImageHeader {
  std::int64_t width = 0, height = 0;
};
ImageHeader peek_image_size(const std::filesystem::path& path);

// Calls `frame(index, image)` for every `stride`-th frame (at most max_frames;
// 0 = all); returns the frame count used. Throws when the file cannot be
// opened, holds no frame, or ends before the frames its header declares.
std::size_t read_video(const std::filesystem::path& path, std::size_t stride,
                       std::size_t max_frames,
                       const std::function<void(std::size_t, const Image&)>& frame);

// The image formats write_image writes, by extension.
inline constexpr std::initializer_list<const char*> kImageOutputExtensions = {
    ".png", ".jpg", ".jpeg", ".tif", ".tiff", ".bmp"};
bool is_image_output_path(const std::filesystem::path& path);
// The video containers VideoWriter writes.
inline constexpr std::initializer_list<const char*> kVideoOutputExtensions = {".avi", ".mp4",
                                                                              ".mov", ".mkv"};
bool is_video_output_path(const std::filesystem::path& path);

// An 8-bit image in the format its extension names (PNG, JPEG at quality 95,
// TIFF, BMP), written atomically: PATH.tmp-PID.EXT in the same folder, then
// rename. Refuses to replace an existing file unless `force`.
void write_image(const std::filesystem::path& path, const Image& image, bool force);

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

// Throws a clear error when `path` exists and `force` is false (or is a folder).
void check_writable(const std::filesystem::path& path, bool force);

// While alive, the decoders' messages on stderr (libpng, libjpeg, FFmpeg) are
// discarded, unless --verbose. Not for code that reports anything itself.
class QuietDecoders {
 public:
  QuietDecoders();
  ~QuietDecoders();
  QuietDecoders(const QuietDecoders&) = delete;
  QuietDecoders& operator=(const QuietDecoders&) = delete;

 private:
  int saved_ = -1;
};

// A benchmark's probe video and its clean clip (.png), decoded, as the
// evaluation runs it (probe_run.hpp).
ProbeVideo read_probe_video(const Device& device, const std::filesystem::path& video,
                            const std::filesystem::path& clean, std::uint64_t sampler_seed);

}  // namespace vkjr2::cli
