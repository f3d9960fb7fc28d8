// What a failed command may print and leave: one "vkjr2: error:" line (and
// "vkjr2: warning:" lines), no decoder noise, no temporary file; and the
// media files the command-runner tests feed it.
#pragma once

#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/videoio.hpp>

#include <filesystem>
#include <fstream>
#include <iterator>
#include <sstream>
#include <string>
#include <vector>

namespace vkjr2::test {

// Under AddressSanitizer every command takes seconds to start and stop: the
// tests that run the command many times over run a sample of their cases
// there (memory errors are what that build looks for); the ci build runs all.
#if defined(__SANITIZE_ADDRESS__)
inline constexpr bool kSanitized = true;
#else
inline constexpr bool kSanitized = false;
#endif

// The lines of a command's output.
inline std::vector<std::string> lines_of(const std::string& output) {
  std::vector<std::string> out;
  std::istringstream in(output);
  for (std::string line; std::getline(in, line);)
    if (!line.empty()) out.push_back(line);
  return out;
}

// How many lines start with "vkjr2: error:".
inline int error_lines(const std::string& output) {
  int n = 0;
  for (const std::string& l : lines_of(output)) n += l.starts_with("vkjr2: error:") ? 1 : 0;
  return n;
}

// Every line is the command's own ("vkjr2: error:" / "vkjr2: warning:").
inline bool only_own_lines(const std::string& output) {
  for (const std::string& l : lines_of(output))
    if (!l.starts_with("vkjr2: error:") && !l.starts_with("vkjr2: warning:")) return false;
  return true;
}

// A line the image or video decoders print themselves (libpng, libjpeg,
// FFmpeg's "[mjpeg @ 0x...]", OpenCV's log) rather than through vkjr2.
inline bool has_decoder_noise(const std::string& output) {
  for (const std::string& l : lines_of(output)) {
    if (l.starts_with("vkjr2: ")) continue;
    for (const char* noise : {"libpng", "[ WARN", "[ERROR", "Premature end", "Corrupt JPEG",
                              " @ 0x", "JPEG datastream", "Invalid data"})
      if (l.find(noise) != std::string::npos) return true;
  }
  return false;
}

// Files under `dir` (recursively) whose name holds ".tmp": a temporary output.
inline std::vector<std::filesystem::path> temporaries(const std::filesystem::path& dir) {
  std::vector<std::filesystem::path> out;
  std::error_code ec;
  for (auto it = std::filesystem::recursive_directory_iterator(dir, ec);
       it != std::filesystem::recursive_directory_iterator(); it.increment(ec)) {
    if (it->path().filename().string().find(".tmp") != std::string::npos) out.push_back(it->path());
  }
  return out;
}

// Random pixels (OpenCV's default RNG), in the format the extension names.
inline std::filesystem::path write_noise_image(const std::filesystem::path& path, int h, int w) {
  cv::Mat img(h, w, CV_8UC3);
  cv::randu(img, cv::Scalar::all(0), cv::Scalar::all(255));
  cv::imwrite(path.string(), img);
  return path;
}

// A Motion-JPEG .avi at 10 frames/s whose frame i is `first + i·step` (all channels).
inline bool write_clip(const std::filesystem::path& path, const cv::Mat& first, int frames,
                       double step) {
  cv::VideoWriter w(path.string(), cv::CAP_FFMPEG, cv::VideoWriter::fourcc('M', 'J', 'P', 'G'), 10,
                    first.size());
  if (!w.isOpened()) return false;
  for (int i = 0; i < frames; ++i) w.write(first + cv::Scalar::all(i * step));
  return true;
}

// The first `fraction` of a file's bytes, written to `to`.
inline void write_truncated(const std::filesystem::path& from, const std::filesystem::path& to,
                            double fraction) {
  std::ifstream src(from, std::ios::binary);
  const std::string bytes((std::istreambuf_iterator<char>(src)), std::istreambuf_iterator<char>());
  std::ofstream(to, std::ios::binary)
      << bytes.substr(0, static_cast<std::size_t>(double(bytes.size()) * fraction));
}

}  // namespace vkjr2::test
