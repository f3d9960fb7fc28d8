#include "media.hpp"

#include <vkjr2/runtime/error.hpp>
#include <vkjr2/runtime/image.hpp>
#include <vkjr2/runtime/npy.hpp>

#include <fcntl.h>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <opencv2/videoio.hpp>
#include <unistd.h>

#include <algorithm>
#include <array>
#include <cctype>
#include <cerrno>
#include <cmath>
#include <csetjmp>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <functional>
#include <system_error>

// After <cstdio>: jpeglib.h uses FILE and size_t without including them.
#include <jpeglib.h>

#include "checks.hpp"
#include "cv_image.hpp"
#include "log.hpp"

namespace vkjr2::cli {
namespace {

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
  return has_extension(path, {".png", ".jpg", ".jpeg", ".tif", ".tiff", ".bmp", ".webp", ".npy"});
}

bool is_video_path(const std::filesystem::path& path) {
  return has_extension(path, {".avi", ".mp4", ".mkv", ".mov", ".webm", ".m4v", ".mpg", ".mpeg"});
}

namespace {

[[noreturn]] void unreadable(const std::string& source, int err) {
  if (err == EACCES || err == EPERM) {
    throw Error("read", "permission denied reading " + source,
                "give yourself read permission (chmod u+r) or run as the file's owner");
  }
  throw Error("read", "cannot read " + source + ": " + std::strerror(err), "check the file");
}

std::vector<unsigned char> read_bytes(const std::filesystem::path& path) {
  const std::string source = path.string();
  std::error_code ec;
  if (!std::filesystem::exists(path, ec)) {
    if (ec) unreadable(source, ec.value());
    throw Error("read", source + " does not exist", "check the path");
  }
  if (std::filesystem::is_directory(path, ec)) {
    throw Error("read", source + " is a folder, not a file", "name a file");
  }
  const int fd = ::open(path.c_str(), O_RDONLY | O_CLOEXEC);
  if (fd < 0) unreadable(source, errno);
  std::vector<unsigned char> bytes;
  std::array<unsigned char, 1 << 16> buf{};
  for (;;) {
    const ssize_t n = ::read(fd, buf.data(), buf.size());
    if (n < 0) {
      if (errno == EINTR) continue;
      const int err = errno;
      ::close(fd);
      unreadable(source, err);
    }
    if (n == 0) break;
    bytes.insert(bytes.end(), buf.begin(), buf.begin() + n);
  }
  ::close(fd);
  return bytes;
}

std::uint32_t be32(const unsigned char* p) {
  return (std::uint32_t(p[0]) << 24) | (std::uint32_t(p[1]) << 16) | (std::uint32_t(p[2]) << 8) |
         std::uint32_t(p[3]);
}

std::uint32_t le32(const unsigned char* p) {
  return (std::uint32_t(p[3]) << 24) | (std::uint32_t(p[2]) << 16) | (std::uint32_t(p[1]) << 8) |
         std::uint32_t(p[0]);
}

// ---- JPEG: libjpeg with every warning ("Premature end of JPEG file",
// "Corrupt JPEG data") taken as an error; OpenCV's decoder only prints them.

struct JpegError {
  jpeg_error_mgr mgr;
  std::jmp_buf jump;
  char message[JMSG_LENGTH_MAX];
};

[[noreturn]] void jpeg_fail(j_common_ptr cinfo) {
  auto* e = reinterpret_cast<JpegError*>(cinfo->err);  // NOLINT: mgr is the first member
  (*cinfo->err->format_message)(cinfo, e->message);
  std::longjmp(e->jump, 1);
}

void jpeg_message(j_common_ptr cinfo, int level) {
  if (level < 0) jpeg_fail(cinfo);  // a warning: the data is damaged
}

struct JpegScan {
  bool ok = false;
  std::int64_t width = 0, height = 0;
  char message[JMSG_LENGTH_MAX] = {};
};

// Reads the header (and with `decode`, every scanline) of an in-memory JPEG.
// Plain C data only between setjmp and longjmp.
JpegScan scan_jpeg(const unsigned char* data, std::size_t size, bool decode) {
  JpegScan out;
  jpeg_decompress_struct cinfo{};
  JpegError err{};
  cinfo.err = jpeg_std_error(&err.mgr);
  err.mgr.error_exit = jpeg_fail;
  err.mgr.emit_message = jpeg_message;
  if (setjmp(err.jump) != 0) {  // NOLINT(cert-err52-cpp): libjpeg's error protocol
    std::memcpy(out.message, err.message, sizeof out.message);
    jpeg_destroy_decompress(&cinfo);
    out.ok = false;
    return out;
  }
  jpeg_create_decompress(&cinfo);
  jpeg_mem_src(&cinfo, data, static_cast<unsigned long>(size));
  jpeg_read_header(&cinfo, TRUE);
  out.width = cinfo.image_width;
  out.height = cinfo.image_height;
  const bool small_enough = out.width * out.height <= kMaxImagePixels &&
                            out.width <= kMaxImageSide * 4 && out.height <= kMaxImageSide * 4;
  if (decode && small_enough) {
    jpeg_start_decompress(&cinfo);
    JSAMPARRAY row = (*cinfo.mem->alloc_sarray)(reinterpret_cast<j_common_ptr>(&cinfo), JPOOL_IMAGE,
                                                cinfo.output_width * cinfo.output_components, 1);
    while (cinfo.output_scanline < cinfo.output_height) jpeg_read_scanlines(&cinfo, row, 1);
    jpeg_finish_decompress(&cinfo);
  }
  jpeg_destroy_decompress(&cinfo);
  out.ok = true;
  return out;
}

bool is_jpeg(const std::vector<unsigned char>& b) {
  return b.size() >= 3 && b[0] == 0xFF && b[1] == 0xD8 && b[2] == 0xFF;
}
bool is_png(const std::vector<unsigned char>& b) {
  static constexpr unsigned char kSig[8] = {0x89, 'P', 'N', 'G', 0x0D, 0x0A, 0x1A, 0x0A};
  return b.size() >= 8 && std::equal(kSig, kSig + 8, b.begin());
}
bool is_bmp(const std::vector<unsigned char>& b) {
  return b.size() >= 2 && b[0] == 'B' && b[1] == 'M';
}

[[noreturn]] void corrupt(const std::string& source, const std::string& detail) {
  throw Error("read_image",
              "cannot decode " + source + ": the file is truncated or corrupt" +
                  (detail.empty() ? std::string() : " (" + detail + ")"),
              "re-export or re-download the file");
}

void check_size(const std::string& source, std::int64_t width, std::int64_t height) {
  if (width <= 0 || height <= 0) corrupt(source, "its header gives a size of 0");
  if (width > kMaxImageSide || height > kMaxImageSide || width * height > kMaxImagePixels) {
    throw Error("read_image",
                source + " is " + std::to_string(width) + "x" + std::to_string(height) +
                    " pixels: image too large (the limit is " + std::to_string(kMaxImageSide) +
                    "x" + std::to_string(kMaxImageSide) + ")",
                "scale or crop it to at most " + std::to_string(kMaxImageSide) + " pixels a side");
  }
}

// The header's size, and for JPEG, PNG and BMP whether the file is whole.
ImageHeader inspect(const std::vector<unsigned char>& b, const std::string& source, bool full) {
  ImageHeader h;
  if (is_png(b)) {
    if (b.size() < 24 || std::memcmp(&b[12], "IHDR", 4) != 0) corrupt(source, "no PNG header");
    h.width = be32(&b[16]);
    h.height = be32(&b[20]);
    check_size(source, h.width, h.height);
    // The decoder reports a truncated PNG itself (libpng read error).
  } else if (is_jpeg(b)) {
    const JpegScan s = scan_jpeg(b.data(), b.size(), false);
    if (!s.ok) corrupt(source, s.message);
    h.width = s.width;
    h.height = s.height;
    check_size(source, h.width, h.height);
    if (full) {
      const JpegScan d = scan_jpeg(b.data(), b.size(), true);
      if (!d.ok) corrupt(source, d.message);
    }
  } else if (is_bmp(b)) {
    if (b.size() < 26) corrupt(source, "no BMP header");
    const std::uint32_t declared = le32(&b[2]);
    h.width = std::int32_t(le32(&b[18]));
    h.height = std::abs(std::int64_t(std::int32_t(le32(&b[22]))));
    check_size(source, h.width, h.height);
    if (declared > 0 && b.size() < declared) {
      corrupt(source, std::to_string(b.size()) + " of the " + std::to_string(declared) +
                          " bytes its header declares");
    }
  }
  return h;
}

// .npy: H×W×3 RGB, H×W×1 or H×W grey (a leading 1 allowed), float32 in 0..255.
Image read_npy_image(const std::filesystem::path& path) {
  const std::string source = path.string();
  Image img = vkjr2::read_npy(path);
  if (img.shape.size() == 4 && img.shape[0] == 1) img.shape.erase(img.shape.begin());
  if (img.shape.size() == 2) img.shape.push_back(1);
  const bool ok_shape = img.shape.size() == 3 && (img.shape[2] == 3 || img.shape[2] == 1) &&
                        img.shape[0] > 0 && img.shape[1] > 0;
  if (!ok_shape) {
    throw Error("read_image", source + " has shape " + vkjr2::shape_str(img.shape),
                "save images as float32 arrays of shape (height, width, 3) RGB or (height, "
                "width) grey, in 0..255");
  }
  check_size(source, img.shape[1], img.shape[0]);
  float lo = 0, hi = 0;
  bool first = true;
  for (float v : img.values) {
    if (!std::isfinite(v)) {
      throw Error("read_image", source + " contains NaN or infinite values",
                  "save finite pixel values in 0..255");
    }
    lo = first ? v : std::min(lo, v);
    hi = first ? v : std::max(hi, v);
    first = false;
  }
  if (lo < 0 || hi > 255) {
    char range[96];
    std::snprintf(range, sizeof range, "%.6g..%.6g", double(lo), double(hi));
    throw Error("read_image", source + " holds values in " + range + " but pixels are 0..255",
                "scale the array to 0..255 (e.g. np.clip(a, 0, 255))");
  }
  if (hi <= 1.0f && hi > 0) {
    log_warn(source + ": every value is at most 1; if the image is in 0..1, multiply it by 255");
  }
  if (img.shape[2] == 1) {
    std::vector<float> rgb(img.values.size() * 3);
    for (std::size_t i = 0; i < img.values.size(); ++i)
      rgb[3 * i] = rgb[3 * i + 1] = rgb[3 * i + 2] = img.values[i];
    img.values = std::move(rgb);
    img.shape[2] = 3;
  }
  return img;
}

}  // namespace

QuietDecoders::QuietDecoders() {
  if (verbose()) return;
  std::fflush(stderr);
  const int null_fd = ::open("/dev/null", O_WRONLY | O_CLOEXEC);
  if (null_fd < 0) return;
  saved_ = ::fcntl(STDERR_FILENO, F_DUPFD_CLOEXEC, 3);
  if (saved_ >= 0) ::dup2(null_fd, STDERR_FILENO);
  ::close(null_fd);
}

QuietDecoders::~QuietDecoders() {
  if (saved_ < 0) return;
  std::fflush(stderr);
  ::dup2(saved_, STDERR_FILENO);
  ::close(saved_);
}

ImageHeader peek_image_size(const std::filesystem::path& path) {
  if (lower_extension(path) == ".npy") return {};
  return inspect(read_bytes(path), path.string(), false);
}

Image read_image(const std::filesystem::path& path) {
  const std::string source = path.string();
  if (lower_extension(path) == ".npy") {
    if (::access(path.c_str(), R_OK) != 0 && (errno == EACCES || errno == EPERM))
      unreadable(source, errno);
    return read_npy_image(path);
  }
  const std::vector<unsigned char> bytes = read_bytes(path);
  if (bytes.empty()) corrupt(source, "the file is empty");
  inspect(bytes, source, true);
  cv::Mat m;
  try {
    const QuietDecoders quiet;
    m = cv::imdecode(bytes, cv::IMREAD_UNCHANGED);
  } catch (const cv::Exception&) {
    m = cv::Mat();
  }
  if (m.empty()) {
    throw Error("read_image", "cannot decode " + source + " as an image",
                "pass a PNG, JPEG, TIFF, BMP or WebP file (or a float32 .npy array); the file may "
                "be truncated or corrupt");
  }
  check_size(source, m.cols, m.rows);
  return from_mat(m, source);
}

std::size_t read_video(const std::filesystem::path& path, std::size_t stride,
                       std::size_t max_frames,
                       const std::function<void(std::size_t, const Image&)>& frame) {
  const std::string source = path.string();
  std::error_code ec;
  if (!std::filesystem::exists(path, ec))
    throw Error("read_video", source + " does not exist", "check the path");
  if (::access(path.c_str(), R_OK) != 0 && (errno == EACCES || errno == EPERM))
    unreadable(source, errno);
  cv::VideoCapture cap;
  bool opened = false;
  {
    const QuietDecoders quiet;
    try {
      opened = cap.open(source, cv::CAP_FFMPEG);
    } catch (const cv::Exception&) {
      opened = false;
    }
  }
  if (!opened) {
    throw Error("read_video", "cannot open " + source + " as a video",
                "pass a video OpenCV's FFmpeg backend reads (e.g. .avi, .mp4); the file may be "
                "truncated or corrupt");
  }
  const double declared = cap.get(cv::CAP_PROP_FRAME_COUNT);
  stride = std::max<std::size_t>(stride, 1);
  std::size_t decoded = 0, used = 0;
  bool stopped_early = false;
  cv::Mat m;
  for (;;) {
    bool got = false;
    {
      const QuietDecoders quiet;
      try {
        got = cap.read(m);
      } catch (const cv::Exception&) {
        got = false;
      }
    }
    if (!got) break;
    const std::size_t index = decoded++;
    if (index == 0 || m.cols > kMaxImageSide || m.rows > kMaxImageSide) {
      check_size(source, m.cols, m.rows);
    }
    if (index % stride == 0) {
      frame(index, from_mat(m, source + " frame " + std::to_string(index)));
      if (++used == max_frames) {
        stopped_early = true;
        break;
      }
    }
  }
  if (decoded == 0) {
    throw Error("read_video", source + " holds no decodable frame",
                "the file may be truncated or use a codec FFmpeg cannot decode");
  }
  // A container that declares its length (AVI's header does) and ends well
  // before it was cut short.
  if (!stopped_early && std::isfinite(declared) && declared > 2 &&
      double(decoded) + 1 < 0.98 * declared) {
    throw Error("read_video",
                source + " ends after " + std::to_string(decoded) + " of the " +
                    std::to_string(static_cast<long long>(declared)) +
                    " frames its header declares: the file is truncated or corrupt",
                "re-encode or re-download it, or pass --max-frames " + std::to_string(decoded) +
                    " to use the frames before the damage");
  }
  return used;
}

void check_writable(const std::filesystem::path& path, bool force) {
  check_output_file(path, force, "write");
}

bool is_video_output_path(const std::filesystem::path& path) {
  return has_extension(path, kVideoOutputExtensions);
}

bool is_image_output_path(const std::filesystem::path& path) {
  return has_extension(path, kImageOutputExtensions);
}

void write_image(const std::filesystem::path& path, const Image& image, bool force) {
  check_writable(path, force);
  check_extension(path, kImageOutputExtensions, "write");
  if (image.shape.size() != 3 || image.shape[2] != 3) {
    throw InvalidArgument("write_image", "image has shape " + vkjr2::shape_str(image.shape),
                          "pass an H×W×3 RGB image");
  }
  const cv::Mat out = image_to_bgr(image);
  const std::string ext = lower_extension(path);
  const auto tmp =
      path.parent_path() / (path.filename().string() + ".tmp-" + std::to_string(::getpid()) + ext);
  std::vector<int> params;
  if (ext == ".jpg" || ext == ".jpeg") params = {cv::IMWRITE_JPEG_QUALITY, 95};
  bool ok = false;
  try {
    const QuietDecoders quiet;
    ok = cv::imwrite(tmp.string(), out, params);
  } catch (const cv::Exception&) {
    ok = false;
  }
  std::error_code ec;
  if (ok) {
    std::filesystem::rename(tmp, path, ec);
    ok = !ec;
  }
  if (!ok) {
    std::filesystem::remove(tmp, ec);
    throw Error("write_image", "cannot write " + path.string(),
                "check that the folder exists, is writable and has free space");
  }
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
  check_extension(path_, kVideoOutputExtensions, "write_video");
  const std::string ext = lower_extension(path_);
  const int fourcc = ext == ".avi" ? cv::VideoWriter::fourcc('M', 'J', 'P', 'G')
                                   : cv::VideoWriter::fourcc('m', 'p', '4', 'v');
  tmp_ = path_.parent_path() / (path_.stem().string() + ".tmp-" + std::to_string(::getpid()) + ext);
  bool ok = false;
  try {
    const QuietDecoders quiet;
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
    const QuietDecoders quiet;
    state_->writer.release();
    std::error_code ec;
    std::filesystem::remove(tmp_, ec);
  }
}

void VideoWriter::write(const Image& frame) {
  if (frame.shape.size() != 3 || frame.shape[0] != height_ || frame.shape[1] != width_ ||
      frame.shape[2] != 3) {
    throw InvalidArgument("write_video", "frame has shape " + vkjr2::shape_str(frame.shape) +
                                             ", the video is " + std::to_string(height_) + "×" +
                                             std::to_string(width_) + "×3");
  }
  const cv::Mat out = image_to_bgr(frame);
  const QuietDecoders quiet;
  state_->writer.write(out);
  ++frames_;
}

void VideoWriter::finish() {
  if (finished_) return;
  {
    const QuietDecoders quiet;
    state_->writer.release();
  }
  if (frames_ == 0) {
    throw Error("write_video", "no frame was written to " + path_.string(), "check the input");
  }
  std::error_code ec;
  std::filesystem::rename(tmp_, path_, ec);
  if (ec) {
    throw Error("write_video",
                "cannot move the finished video to " + path_.string() + ": " + ec.message(),
                "check that the folder is writable");
  }
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

ProbeVideo read_probe_video(const Device& device, const std::filesystem::path& video,
                            const std::filesystem::path& clean, std::uint64_t sampler_seed) {
  std::vector<HostTensor> frames;
  read_video(video, 1, 0, [&](std::size_t, const Image& img) { frames.push_back(img); });
  return {device, std::move(frames), image_to_device(device, read_image(clean)), clean,
          sampler_seed};
}

}  // namespace vkjr2::cli
