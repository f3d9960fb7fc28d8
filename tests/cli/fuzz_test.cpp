// Every command fed random options with one bad value, or a truncated input
// file: the exit code is 1 or 2, the output has one "vkjr2: error:" line and
// none of the decoders' own, and no file is left behind.
#include <gtest/gtest.h>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/videoio.hpp>

#include <filesystem>
#include <random>
#include <string>
#include <vector>

#include "support/cli_checks.hpp"
#include "support/cli_files.hpp"
#include "support/run_cli.hpp"

namespace {

namespace fs = std::filesystem;
using vkjr2::test::error_lines;
using vkjr2::test::has_decoder_noise;
using vkjr2::test::run_cli;
using vkjr2::test::TempDir;
using vkjr2::test::temporaries;
using vkjr2::test::write_truncated;

// An option, values a user may rightly give it, and values it must refuse.
struct Opt {
  std::string name;
  std::vector<std::string> good, bad;
};

const std::vector<std::string> kBadFloat = {"nan", "inf", "-inf", "abc", "1e999", "-5", "''"};
const std::vector<std::string> kBadCount = {"-1",  "abc", "1.5", "99999999999999999999",
                                            "nan", "''"};
const std::vector<std::string> kBadSeed = {"-1", "1e23", "18446744073709551616", "x", "2.5"};

struct Command {
  std::string name;
  bool takes_input;  // its first positional is an input file a test can truncate
  std::vector<Opt> options;
};

std::vector<Command> commands() {
  const Opt device{"--device", {"0"}, {"99", "no-such-device"}};
  const Opt preset{"--preset", {"weak", "strong"}, {"hurricane", "''"}};
  const Opt seed{"--seed", {"0", "7", "18446744073709551615"}, kBadSeed};
  const Opt input_size{"--input-size", {"320", "416"}, {"33", "0", "-32", "abc", "8192"}};
  const Opt min_score{"--min-score", {"0.3", "0.5"}, kBadFloat};
  return {
      {"simulate",
       true,
       {preset,
        seed,
        device,
        {"--r0", {"0.05", "0.1"}, kBadFloat},
        {"--range", {"500", "1000"}, kBadFloat},
        {"--wavelengths", {"525", "rgb", "610,525,465"}, {"red", "50", "1,2", "5e9", "''"}},
        {"--photons", {"0", "1000"}, kBadFloat},
        {"--read-noise", {"0", "0.01"}, kBadFloat},
        {"--tilt-rho", {"0.5", "0.9"}, kBadFloat},
        {"--high-order-rho", {"0.1"}, kBadFloat},
        {"--frames", {"1"}, {"0", "-3", "abc", "1e3"}},
        {"--max-frames", {"0", "2"}, kBadCount}}},
      {"detect",
       true,
       {device,
        input_size,
        min_score,
        {"--every", {"1", "2"}, {"0", "-1", "abc"}},
        {"--max-frames", {"0", "1"}, kBadCount}}},
      {"embed",
       true,
       {device, input_size, min_score, {"--align", {"similarity"}, {"rigid", "''"}}}},
      {"verify", true, {device, input_size, {"--threshold", {"0.6", "0.4"}, kBadFloat}}},
      {"wave",
       true,
       {preset,
        seed,
        device,
        {"--grid", {"64", "128"}, {"17", "61", "0", "abc", "1e9"}},
        {"--screens", {"2", "3"}, kBadCount},
        {"--source-step", {"24", "32"}, kBadFloat},
        {"--psf-size", {"0", "15"}, {"4", "-1", "100", "abc"}},
        {"--fft", {"device", "fftw"}, {"gpu", "''"}}}},
      {"sim-train",
       false,
       {preset,
        seed,
        device,
        {"--size", {"9"}, {"8", "2", "99", "abc"}},
        {"--count", {"6"}, kBadCount},
        {"--steps", {"10"}, kBadCount},
        {"--wavelength", {"610"}, kBadFloat},
        {"--basis-seed", {"3"}, kBadSeed}}},
      {"demo",
       false,
       {seed,
        device,
        {"--frames", {"1"}, kBadCount},
        {"--photos", {"1", "2"}, {"0", "7", "abc"}},
        {"--width", {"320"}, {"10", "99999", "abc"}}}},
      {"bench sim",
       false,
       {preset,
        device,
        {"--sizes", {"64"}, {"0", "-64", "abc", "99999"}},
        {"--frames", {"1"}, kBadCount},
        {"--wave-grid", {"64"}, {"17", "abc"}},
        {"--wave-step", {"32"}, kBadFloat}}},
  };
}

// Each input a command can take, and truncated or corrupt copies of it.
struct Inputs {
  std::vector<fs::path> images, videos, broken_images, broken_videos;
};

Inputs make_inputs(const fs::path& dir) {
  Inputs in;
  cv::Mat img(72, 96, CV_8UC3);
  cv::randu(img, cv::Scalar::all(0), cv::Scalar::all(255));
  for (const char* ext : {".png", ".jpg", ".bmp"}) {
    const fs::path p = dir / (std::string("img") + ext);
    cv::imwrite(p.string(), img);
    in.images.push_back(p);
    for (const double f : {0.1, 0.5, 0.95}) {
      const fs::path cut = dir / ("cut" + std::to_string(int(f * 100)) + ext);
      write_truncated(p, cut, f);
      in.broken_images.push_back(cut);
    }
  }
  const fs::path video = dir / "clip.avi";
  vkjr2::test::write_clip(video, img, 24, 4);
  in.videos.push_back(video);
  for (const double f : {0.05, 0.5}) {
    const fs::path cut = dir / ("cut" + std::to_string(int(f * 100)) + ".avi");
    write_truncated(video, cut, f);
    in.broken_videos.push_back(cut);
  }
  return in;
}

TEST(CliFuzz, RandomBadOptionsAndTruncatedFiles) {
  constexpr unsigned kSeed = 20261205;
  std::mt19937 rng(kSeed);
  TempDir tmp("fuzz");
  const fs::path in_dir = tmp.path / "in", out_dir = tmp.path / "out";
  fs::create_directories(in_dir);
  fs::create_directories(out_dir);
  const Inputs inputs = make_inputs(in_dir);
  const auto cmds = commands();
  const auto pick = [&](const auto& v) {
    return v[std::uniform_int_distribution<std::size_t>(0, v.size() - 1)(rng)];
  };
  constexpr int kCases = vkjr2::test::kSanitized ? 16 : 64;
  for (int k = 0; k < kCases; ++k) {
    const Command& c = cmds[k % cmds.size()];
    // Half the cases of commands with an input file: a broken file and good
    // options only; the others: random good options and one bad value.
    const bool broken_file = c.takes_input && (k / int(cmds.size())) % 2 == 1;
    std::string args = c.name;
    const bool video = c.name != "embed" && c.name != "verify" && c.name != "wave" &&
                       std::uniform_int_distribution<int>(0, 3)(rng) == 0;
    if (c.takes_input) {
      const fs::path file = broken_file
                                ? (video ? pick(inputs.broken_videos) : pick(inputs.broken_images))
                                : (video ? pick(inputs.videos) : pick(inputs.images));
      args += " " + file.string();
      if (c.name == "verify") args += " " + pick(inputs.images).string();
    }
    if (c.name == "simulate") args += " " + (out_dir / (video ? "o.avi" : "o.png")).string();
    if (c.name == "wave") args += " " + (out_dir / "o.png").string();
    if (c.name == "sim-train") args += " " + (out_dir / "m.safetensors").string();
    if (c.name == "demo") args += " --out " + (out_dir / "demo").string();
    if (!broken_file) {
      std::vector<Opt> opts = c.options;
      std::shuffle(opts.begin(), opts.end(), rng);
      const int n_good = std::uniform_int_distribution<int>(0, 2)(rng);
      for (int i = 0; i < n_good && i + 1 < int(opts.size()); ++i)
        args += " " + opts[std::size_t(i)].name + " " + pick(opts[std::size_t(i)].good);
      const Opt& bad = opts.back();
      args += " " + bad.name + " " + pick(bad.bad);
    }
    if (c.name != "detect" && c.name != "embed" && c.name != "verify") args += " --quiet";
    SCOPED_TRACE("case " + std::to_string(k) + " (seed " + std::to_string(kSeed) + "): vkjr2 " +
                 args);
    const auto r = run_cli(args);
    EXPECT_TRUE(r.code == 1 || r.code == 2) << r.code << "\n" << r.output;
    EXPECT_EQ(error_lines(r.output), 1) << r.output;
    // detect's text mode prints each frame's faces as it goes: results, not noise.
    EXPECT_FALSE(has_decoder_noise(r.output)) << r.output;
    EXPECT_TRUE(fs::is_empty(out_dir)) << r.output;
    EXPECT_TRUE(temporaries(tmp.path).empty()) << r.output;
    for (const auto& e : fs::directory_iterator(out_dir)) fs::remove_all(e.path());
  }
}

}  // namespace
