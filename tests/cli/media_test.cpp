// Reading and writing media (cli/media.cpp) as a user meets it: truncated and
// corrupt files are errors, formats follow extensions, .npy grey and range
// checks, size limits named up front, decoder noise kept off the terminal.
#include <gtest/gtest.h>
#include <nlohmann/json.hpp>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/videoio.hpp>
#include <sys/wait.h>
#include <unistd.h>

#include <array>
#include <cstdint>
#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include "support/cli_checks.hpp"
#include "support/cli_files.hpp"
#include "support/run_cli.hpp"

namespace {

namespace fs = std::filesystem;
using nlohmann::json;
using vkjr2::test::error_lines;
using vkjr2::test::only_own_lines;
using vkjr2::test::parse_json;
using vkjr2::test::run_cli;
using vkjr2::test::TempDir;
using vkjr2::test::temporaries;
using vkjr2::test::write_truncated;

constexpr const char* kVtest = "/usr/share/doc/opencv-doc/examples/data/vtest.avi";

cv::Mat scene(int h, int w) {
  cv::Mat img(h, w, CV_8UC3);
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x)
      img.at<cv::Vec3b>(y, x) = {static_cast<unsigned char>((x * 7 + y * 3) % 256),
                                 static_cast<unsigned char>(((x / 5 + y / 5) % 2) * 200),
                                 static_cast<unsigned char>(y % 256)};
  return img;
}

fs::path write_image(const fs::path& path, int h, int w) {
  cv::imwrite(path.string(), scene(h, w));
  return path;
}

// A little-endian float32 .npy of the given shape.
fs::path write_npy(const fs::path& path, const std::vector<int>& shape,
                   const std::vector<float>& values) {
  std::string dims;
  for (int d : shape) dims += std::to_string(d) + ", ";
  if (shape.size() > 1) dims.resize(dims.size() - 2);
  std::string header = "{'descr': '<f4', 'fortran_order': False, 'shape': (" + dims + "), }";
  while ((10 + header.size() + 1) % 64 != 0) header += ' ';
  header += '\n';
  std::ofstream f(path, std::ios::binary);
  f.write("\x93NUMPY\x01\x00", 8);
  const auto len = static_cast<std::uint16_t>(header.size());
  f.put(char(len & 0xff)).put(char(len >> 8));
  f << header;
  f.write(reinterpret_cast<const char*>(values.data()),
          static_cast<std::streamsize>(values.size() * sizeof(float)));
  return path;
}

// A PNG that is a signature and an IHDR claiming w × h pixels, nothing else.
fs::path write_png_header(const fs::path& path, std::uint32_t w, std::uint32_t h) {
  std::string b = "\x89PNG\r\n\x1a\n";
  b += std::string("\0\0\0\x0dIHDR", 8);
  for (std::uint32_t v : {w, h})
    for (int s = 24; s >= 0; s -= 8) b += char((v >> s) & 0xff);
  b += std::string("\x08\x02\0\0\0", 5);
  b += std::string(4, '\0');  // CRC (never reached)
  std::ofstream(path, std::ios::binary) << b;
  return path;
}

void expect_failure(const vkjr2::test::CliResult& r, int code, const std::string& needle,
                    const std::string& what) {
  EXPECT_EQ(r.code, code) << what << "\n" << r.output;
  EXPECT_EQ(error_lines(r.output), 1) << what << "\n" << r.output;
  EXPECT_TRUE(only_own_lines(r.output)) << what << ": decoder noise?\n" << r.output;
  EXPECT_NE(r.output.find(needle), std::string::npos) << what << "\n" << r.output;
}

// Issue case 1: --max-frames 1 on a valid video uses exactly one frame.
TEST(CliMedia, MaxFramesOneReadsOneFrame) {
  TempDir tmp("media_max1");
  const fs::path clip = tmp.path / "clip.avi";
  ASSERT_TRUE(vkjr2::test::write_clip(clip, scene(48, 64), 5, 0));
  std::vector<std::string> videos{clip.string()};
  if (!vkjr2::test::kSanitized) {  // the user's case, full size
    ASSERT_TRUE(fs::exists(kVtest)) << "run scripts/setup (Debian's opencv-doc)";
    videos.emplace_back(kVtest);
  }
  for (const std::string& video : videos) {
    const auto r = run_cli("detect " + video + " --max-frames 1 --json");
    ASSERT_EQ(r.code, 0) << r.output;
    EXPECT_EQ(parse_json(r.output)["frames"].size(), 1u) << r.output;
  }
  const auto s = run_cli("simulate " + clip.string() + " " + (tmp.path / "one.avi").string() +
                         " --max-frames 1 --json --quiet");
  ASSERT_EQ(s.code, 0) << s.output;
  EXPECT_EQ(parse_json(s.output)["frames"], 1);
}

// Issue case 2 (and 12, 13): a truncated or corrupt image is an error, without
// the decoders' own lines; permission denied is said as such.
TEST(CliMedia, TruncatedAndCorruptImagesAreErrors) {
  TempDir tmp("media_truncated");
  const fs::path jpg = write_image(tmp.path / "whole.jpg", 96, 128);
  const fs::path png = write_image(tmp.path / "whole.png", 96, 128);
  const fs::path bmp = write_image(tmp.path / "whole.bmp", 96, 128);
  const fs::path out = tmp.path / "out";
  fs::create_directories(out);
  ASSERT_EQ(run_cli("simulate " + jpg.string() + " " + (out / "ok.png").string() + " --quiet").code,
            0);
  fs::remove(out / "ok.png");
  const std::vector<double> fractions =
      vkjr2::test::kSanitized ? std::vector<double>{0.5} : std::vector<double>{0.5, 0.9};
  for (const fs::path& whole : {jpg, png, bmp}) {
    for (const double fraction : fractions) {
      const fs::path cut = tmp.path / ("cut_" + std::to_string(int(fraction * 100)) + "_" +
                                       whole.filename().string());
      write_truncated(whole, cut, fraction);
      const auto r =
          run_cli("simulate " + cut.string() + " " + (out / "o.png").string() + " --quiet");
      expect_failure(r, 1, "truncated or corrupt", cut.string());
      EXPECT_NE(r.output.find(cut.filename().string()), std::string::npos) << r.output;
      const auto d = run_cli("detect " + cut.string());
      expect_failure(d, 1, "truncated or corrupt", cut.string());
    }
  }
  // Bytes flipped in the middle of the JPEG's entropy-coded data.
  {
    std::ifstream src(jpg, std::ios::binary);
    std::string bytes((std::istreambuf_iterator<char>(src)), std::istreambuf_iterator<char>());
    for (std::size_t i = bytes.size() / 2; i < bytes.size() / 2 + 40; ++i) bytes[i] = '\xff';
    std::ofstream(tmp.path / "flipped.jpg", std::ios::binary) << bytes;
    expect_failure(run_cli("detect " + (tmp.path / "flipped.jpg").string()), 1,
                   "truncated or corrupt", "flipped.jpg");
  }
  EXPECT_TRUE(fs::is_empty(out)) << "an output was written for a bad input";
  EXPECT_TRUE(temporaries(tmp.path).empty());

  // Permission denied, as a user who cannot read the file (root reads
  // everything, so the command runs as nobody when the test runs as root).
  const fs::path locked = tmp.path / "locked.png";
  fs::copy_file(png, locked);
  fs::permissions(locked, fs::perms::none);
  std::string as_user;
  if (::geteuid() == 0) {
    ASSERT_EQ(std::system("command -v setpriv >/dev/null"), 0) << "util-linux's setpriv";
    as_user = "setpriv --reuid=65534 --regid=65534 --clear-groups";
  }
  const auto r = run_cli("simulate " + locked.string() + " " + (out / "l.png").string(), as_user);
  expect_failure(r, 1, "ermission denied", "locked.png");
  EXPECT_EQ(r.output.find("corrupt"), std::string::npos) << r.output;
}

// Issue cases 13 and 14: a header that claims a huge image is refused before
// decoding, with the limit named; simulate names its own, smaller limit.
TEST(CliMedia, TooLargeImagesAreRefusedUpFront) {
  TempDir tmp("media_large");
  const fs::path huge = write_png_header(tmp.path / "huge.png", 100000, 100000);
  expect_failure(run_cli("detect " + huge.string()), 1, "image too large", "huge.png");
  const auto r = run_cli("simulate " + huge.string() + " " + (tmp.path / "o.png").string());
  expect_failure(r, 1, "4096x4096", "huge.png");
  // 4000x4000 is within the reading limit, beyond what the simulator binds on
  // lavapipe (128 MiB buffers): refused from the header (the file holds no
  // pixels, so a decode would have failed as corrupt), with the limit named.
  const fs::path big = write_png_header(tmp.path / "big.png", 4000, 4000);
  const auto s = run_cli("simulate " + big.string() + " " + (tmp.path / "o.png").string());
  expect_failure(s, 1, "too large to simulate", "big.png");
  EXPECT_NE(s.output.find(" MP, e.g. "), std::string::npos) << s.output;
  EXPECT_EQ(s.output.find("corrupt"), std::string::npos) << s.output;
  EXPECT_FALSE(fs::exists(tmp.path / "o.png"));
  const auto help = run_cli("simulate --help");
  EXPECT_NE(help.output.find("1182x1182"), std::string::npos) << help.output;
  EXPECT_NE(run_cli("--help").output.find("4096x4096"), std::string::npos);
}

// Issue case 5: the written file's format follows its extension.
TEST(CliMedia, OutputFormatFollowsTheExtension) {
  TempDir tmp("media_formats");
  const fs::path in = write_image(tmp.path / "in.png", 48, 64);
  const auto magic = [](const fs::path& p) {
    std::ifstream f(p, std::ios::binary);
    std::array<unsigned char, 4> m{};
    f.read(reinterpret_cast<char*>(m.data()), 4);
    return m;
  };
  ASSERT_EQ(run_cli("detect " + in.string() + " --draw " + (tmp.path / "d.jpg").string()).code, 0);
  EXPECT_EQ(magic(tmp.path / "d.jpg")[0], 0xFF);
  EXPECT_EQ(magic(tmp.path / "d.jpg")[1], 0xD8);
  ASSERT_EQ(
      run_cli("simulate " + in.string() + " " + (tmp.path / "s.tif").string() + " --quiet").code,
      0);
  EXPECT_TRUE(magic(tmp.path / "s.tif")[0] == 'I' || magic(tmp.path / "s.tif")[0] == 'M');
  ASSERT_EQ(
      run_cli("simulate " + in.string() + " " + (tmp.path / "s.bmp").string() + " --quiet").code,
      0);
  EXPECT_EQ(magic(tmp.path / "s.bmp")[0], 'B');
  ASSERT_EQ(
      run_cli("simulate " + in.string() + " " + (tmp.path / "s.png").string() + " --quiet").code,
      0);
  EXPECT_EQ(magic(tmp.path / "s.png")[1], 'P');
  const auto r = run_cli("detect " + in.string() + " --draw " + (tmp.path / "d.gif").string());
  expect_failure(r, 2, ".gif", "d.gif");
  EXPECT_FALSE(fs::exists(tmp.path / "d.gif"));
}

// Issue case 6: .npy grey images of shape (H, W) and (H, W, 1) are taken;
// values outside 0..255 are an error, not a black picture.
TEST(CliMedia, NpyGreyShapesAndRange) {
  TempDir tmp("media_npy");
  std::vector<float> grey(24 * 32);
  for (std::size_t i = 0; i < grey.size(); ++i) grey[i] = float(i % 200);
  const fs::path hw = write_npy(tmp.path / "hw.npy", {24, 32}, grey);
  const fs::path hw1 = write_npy(tmp.path / "hw1.npy", {24, 32, 1}, grey);
  for (const fs::path& in : {hw, hw1}) {
    const fs::path out = tmp.path / (in.stem().string() + ".png");
    const auto r = run_cli("simulate " + in.string() + " " + out.string() + " --json --quiet");
    ASSERT_EQ(r.code, 0) << r.output;
    EXPECT_EQ(parse_json(r.output)["width"], 32);
  }
  std::vector<float> negative = grey;
  negative[5] = -3.5f;
  const fs::path neg = write_npy(tmp.path / "neg.npy", {24, 32}, negative);
  expect_failure(run_cli("simulate " + neg.string() + " " + (tmp.path / "n.png").string()), 1,
                 "0..255", "neg.npy");
  std::vector<float> bright = grey;
  bright[7] = 300.f;
  const fs::path hot = write_npy(tmp.path / "hot.npy", {24, 32, 1}, bright);
  expect_failure(run_cli("detect " + hot.string()), 1, "0..255", "hot.npy");
  EXPECT_FALSE(fs::exists(tmp.path / "n.png"));
}

// A video cut short is an error (not a silently shorter result), and the
// MJPEG decoder's complaints stay off the terminal.
TEST(CliMedia, TruncatedVideoIsAnError) {
  TempDir tmp("media_video");
  const fs::path clip = tmp.path / "clip.avi";
  ASSERT_TRUE(vkjr2::test::write_clip(clip, scene(48, 64), 30, 1));
  write_truncated(clip, tmp.path / "cut.avi", 0.5);
  const fs::path out = tmp.path / "out.avi";
  const auto r = run_cli("simulate " + (tmp.path / "cut.avi").string() + " " + out.string() +
                         " --quiet --no-blur");
  expect_failure(r, 1, "cut.avi", "cut.avi");
  EXPECT_FALSE(fs::exists(out));
  EXPECT_TRUE(temporaries(tmp.path).empty());
  const auto d = run_cli("detect " + (tmp.path / "cut.avi").string() + " --json");
  expect_failure(d, 1, "truncated", "cut.avi detect");
  // The frames before the damage can still be used, as the message says.
  const auto ok = run_cli("detect " + (tmp.path / "cut.avi").string() + " --max-frames 3 --json");
  EXPECT_EQ(ok.code, 0) << ok.output;
}

}  // namespace
