// `vkjr2 simulate` and `vkjr2 sim-train` as a user runs them.
#include <gtest/gtest.h>
#include <nlohmann/json.hpp>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/videoio.hpp>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <string>

#include "support/cli_files.hpp"
#include "support/run_cli.hpp"

namespace {

namespace fs = std::filesystem;
using nlohmann::json;
using vkjr2::test::parse_json;
using vkjr2::test::run_cli;
using vkjr2::test::TempDir;

// A checkerboard with a gradient: edges everywhere for the warp to move.
fs::path write_scene(const fs::path& dir, int h, int w) {
  cv::Mat img(h, w, CV_8UC3);
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) {
      const auto v = static_cast<unsigned char>(((x / 6 + y / 6) % 2) ? 200 : 40 + x % 50);
      img.at<cv::Vec3b>(y, x) = {v, static_cast<unsigned char>(255 - v),
                                 static_cast<unsigned char>(y % 256)};
    }
  fs::path p = dir / "scene.png";
  cv::imwrite(p.string(), img);
  return p;
}

double mean_abs_diff(const cv::Mat& a, const cv::Mat& b) {
  cv::Mat d;
  cv::absdiff(a, b, d);
  const cv::Scalar m = cv::mean(d);
  return (m[0] + m[1] + m[2]) / 3;
}

TEST(CliSimulate, ImageToImageIsTurbulentAndSeeded) {
  TempDir tmp("simulate_image");
  const fs::path in = write_scene(tmp.path, 64, 80);
  const fs::path a = tmp.path / "a.png", b = tmp.path / "b.png", c = tmp.path / "c.png";
  const auto r = run_cli("simulate " + in.string() + " " + a.string() +
                         " --preset strong --seed 5 --json --quiet");
  ASSERT_EQ(r.code, 0) << r.output;
  const json j = parse_json(r.output);
  EXPECT_EQ(j["frames"], 1);
  EXPECT_EQ(j["width"], 80);
  EXPECT_GT(j["d_over_r0"].get<double>(), 5);
  ASSERT_EQ(
      run_cli("simulate " + in.string() + " " + b.string() + " --preset strong --seed 5 --quiet")
          .code,
      0);
  ASSERT_EQ(
      run_cli("simulate " + in.string() + " " + c.string() + " --preset strong --seed 6 --quiet")
          .code,
      0);
  const cv::Mat src = cv::imread(in.string()), ia = cv::imread(a.string()),
                ib = cv::imread(b.string()), ic = cv::imread(c.string());
  ASSERT_FALSE(ia.empty());
  EXPECT_EQ(mean_abs_diff(ia, ib), 0.0);   // same seed, same image
  EXPECT_GT(mean_abs_diff(ia, ic), 1.0);   // another seed, another turbulence
  EXPECT_GT(mean_abs_diff(ia, src), 5.0);  // visibly degraded
  // An existing output is not replaced without --force (a usage error, exit 2).
  const auto again = run_cli("simulate " + in.string() + " " + a.string() + " --quiet");
  EXPECT_EQ(again.code, 2);
  EXPECT_NE(again.output.find("--force"), std::string::npos) << again.output;
}

TEST(CliSimulate, ImageToVideoAndVideoToVideoWithFields) {
  TempDir tmp("simulate_video");
  const fs::path in = write_scene(tmp.path, 48, 64);
  const fs::path clip = tmp.path / "clip.avi", clip2 = tmp.path / "clip2.avi",
                 fields = tmp.path / "fields";
  auto r = run_cli("simulate " + in.string() + " " + clip.string() +
                   " --frames 4 --quiet --dump-fields " + fields.string());
  ASSERT_EQ(r.code, 0) << r.output;
  for (const char* f : {"tilt_x.png", "tilt_y.png", "beta_00.png", "beta_01.png", "fields.json"})
    EXPECT_TRUE(fs::exists(fields / f)) << f;
  cv::VideoCapture cap(clip.string());
  ASSERT_TRUE(cap.isOpened());
  int frames = 0;
  cv::Mat m, first;
  double change = 0;
  while (cap.read(m)) {
    if (frames == 0)
      first = m.clone();
    else
      change += mean_abs_diff(first, m);
    ++frames;
  }
  EXPECT_EQ(frames, 4);
  EXPECT_GT(change, 0.0);  // the turbulence moves from frame to frame
  r = run_cli("simulate " + clip.string() + " " + clip2.string() +
              " --max-frames 2 --no-blur --json --quiet");
  ASSERT_EQ(r.code, 0) << r.output;
  EXPECT_EQ(parse_json(r.output)["frames"], 2);
  // No temporary files are left beside the outputs.
  for (const auto& e : fs::directory_iterator(tmp.path))
    EXPECT_EQ(e.path().filename().string().find(".tmp-"), std::string::npos) << e.path();
}

TEST(CliSimulate, BadInputsAreOneLineErrors) {
  TempDir tmp("simulate_bad");
  const fs::path in = write_scene(tmp.path, 32, 32);
  const fs::path out = tmp.path / "out.png";
  // Exit code 2 for a mistake on the command line, 1 for a file that cannot be used.
  auto r = run_cli("simulate " + (tmp.path / "missing.png").string() + " " + out.string());
  EXPECT_EQ(r.code, 2);
  EXPECT_NE(r.output.find("does not exist"), std::string::npos) << r.output;
  {
    std::ofstream bad(tmp.path / "corrupt.avi");
    bad << "not a video";
  }
  r = run_cli("simulate " + (tmp.path / "corrupt.avi").string() + " " +
              (tmp.path / "o.avi").string());
  EXPECT_EQ(r.code, 1) << r.output;
  EXPECT_FALSE(fs::exists(tmp.path / "o.avi"));
  r = run_cli("simulate " + in.string() + " " + out.string() + " --cn2 -1");
  EXPECT_EQ(r.code, 2);
  EXPECT_NE(r.output.find("--cn2"), std::string::npos) << r.output;
  r = run_cli("simulate " + in.string() + " " + out.string() + " --frames 3");
  EXPECT_EQ(r.code, 2);
  EXPECT_NE(r.output.find("video output"), std::string::npos) << r.output;
  r = run_cli("simulate " + in.string() + " " + out.string() + " --blur-model " + in.string());
  EXPECT_EQ(r.code, 1);
  EXPECT_FALSE(fs::exists(out));
  r = run_cli("simulate " + in.string() + " " + out.string() + " --preset hurricane");
  EXPECT_EQ(r.code, 2);
  // A config with its own pixel pitch samples the PSF where no shipped model
  // does: the error gives the sim-train command that makes one, and how to pass it.
  std::ofstream(tmp.path / "pitch.yaml") << "preset: moderate\noptics:\n  pixel_pitch_m: 5.0e-6\n";
  r = run_cli("simulate " + in.string() + " " + out.string() + " --config " +
              (tmp.path / "pitch.yaml").string());
  EXPECT_EQ(r.code, 1) << r.output;
  EXPECT_NE(r.output.find("`vkjr2 sim-train p2s_ch0.safetensors --config " +
                          (tmp.path / "pitch.yaml").string() + " --channel 0`"),
            std::string::npos)
      << r.output;
  EXPECT_NE(r.output.find("--blur-model"), std::string::npos) << r.output;
  EXPECT_FALSE(fs::exists(out));
  r = run_cli("simulate --help");
  EXPECT_EQ(r.code, 0);
  EXPECT_NE(r.output.find("Examples"), std::string::npos);
}

// A folder in, a folder out: one output per image or video, named after it,
// each with its own seed (seed + position); other files are ignored.
TEST(CliSimulate, FolderToFolder) {
  TempDir tmp("simulate_folder");
  const fs::path in = tmp.path / "in", out = tmp.path / "out";
  fs::create_directories(in);
  const fs::path scene = write_scene(tmp.path, 40, 48);
  fs::copy_file(scene, in / "a.png");
  fs::copy_file(scene, in / "b.png");
  {
    std::ofstream notes(in / "notes.txt");
    notes << "not an image";
  }
  auto r = run_cli("simulate " + in.string() + " " + out.string() +
                   " --preset strong --seed 3 --json --quiet --log-level info");
  ASSERT_EQ(r.code, 0) << r.output;
  EXPECT_NE(r.output.find("vkjr2: info: device"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("vkjr2: info: wrote " + (out / "a.png").string()), std::string::npos)
      << r.output;
  const json j = parse_json(r.output.substr(r.output.find('{')));
  ASSERT_EQ(j["files"].size(), 2u);
  EXPECT_EQ(j["files"][0]["seed"], 3);
  EXPECT_EQ(j["files"][1]["seed"], 4);
  EXPECT_EQ(j["files"][1]["output"], (out / "b.png").string());
  ASSERT_TRUE(fs::exists(out / "a.png"));
  ASSERT_TRUE(fs::exists(out / "b.png"));
  EXPECT_FALSE(fs::exists(out / "notes.png"));
  // Same input, different seeds → different turbulence.
  const cv::Mat a = cv::imread((out / "a.png").string()), b = cv::imread((out / "b.png").string());
  EXPECT_GT(mean_abs_diff(a, b), 1.0);
  // Without --force nothing is overwritten, and the refusal comes before any work.
  r = run_cli("simulate " + in.string() + " " + out.string() + " --quiet");
  EXPECT_EQ(r.code, 2);
  EXPECT_NE(r.output.find("already exists"), std::string::npos) << r.output;
  // Default log level: no info lines.
  r = run_cli("simulate " + in.string() + " " + out.string() + " --quiet --force");
  ASSERT_EQ(r.code, 0) << r.output;
  EXPECT_EQ(r.output.find("vkjr2: info:"), std::string::npos) << r.output;
  // A folder IN needs a folder OUT; an empty folder is an error.
  r = run_cli("simulate " + in.string() + " " + (out / "a.png").string() + " --quiet");
  EXPECT_EQ(r.code, 2);
  EXPECT_NE(r.output.find("not a folder"), std::string::npos) << r.output;
  fs::create_directories(tmp.path / "empty");
  r = run_cli("simulate " + (tmp.path / "empty").string() + " " + out.string() + " --quiet");
  EXPECT_EQ(r.code, 2);
  EXPECT_NE(r.output.find("holds no image or video"), std::string::npos) << r.output;
  r = run_cli("devices --log-level loud");
  EXPECT_EQ(r.code, 2) << r.output;
}

TEST(CliSimTrain, TrainsASmallModelTheSimulatorUses) {
  TempDir tmp("sim_train");
  const fs::path model = tmp.path / "tiny.safetensors";
  auto r = run_cli(
      "sim-train " + model.string() +
      " --size 9 --count 6 --psf-samples 200 --train-samples 512 --steps 30 --json --quiet");
  ASSERT_EQ(r.code, 0) << r.output;
  const json j = parse_json(r.output);
  EXPECT_EQ(j["count"], 6);
  EXPECT_LT(j["test_p2s_rel_l2"].get<double>(), 1.0);
  const fs::path in = write_scene(tmp.path, 32, 40);
  r = run_cli("simulate " + in.string() + " " + (tmp.path / "o.png").string() + " --blur-model " +
              model.string() + " --quiet");
  EXPECT_EQ(r.code, 0) << r.output;
  r = run_cli("sim-train " + model.string() + " --size 8");
  EXPECT_NE(r.code, 0);
  // --wavelength: the same optics at another wavelength, which simulate then
  // takes for a channel of that wavelength.
  const fs::path red = tmp.path / "tiny700.safetensors";
  r = run_cli("sim-train " + red.string() +
              " --wavelength 700 --size 9 --count 6 --psf-samples 200 --train-samples 512 "
              "--steps 30 --json --quiet");
  ASSERT_EQ(r.code, 0) << r.output;
  const json jr = parse_json(r.output);
  EXPECT_NEAR(jr["wavelength_nm"].get<double>(), 700, 1e-9);
  EXPECT_NEAR(jr["nyquist"].get<double>(), 700e-9 * 1.6 / (2 * 0.2 * 3.45e-6), 1e-6);
  r = run_cli("simulate " + in.string() + " " + (tmp.path / "red.png").string() +
              " --wavelengths 700 --grey --blur-model " + red.string() + " --quiet");
  EXPECT_EQ(r.code, 0) << r.output;
  r = run_cli("simulate " + in.string() + " " + (tmp.path / "red2.png").string() +
              " --wavelengths 700 --grey --blur-model " + model.string() + " --quiet");
  EXPECT_EQ(r.code, 1) << r.output;
  EXPECT_NE(r.output.find("Nyquist"), std::string::npos) << r.output;
  r = run_cli("sim-train " + red.string() + " --wavelength 700 --channel 1 --force");
  EXPECT_EQ(r.code, 2) << r.output;
}

// One wavelength per channel: the shipped models cover --wavelengths rgb;
// the summary reports each channel's λ, D/r0 and sampling.
TEST(CliSimulate, RgbWavelengthsBlurEachChannelAtItsOwn) {
  TempDir tmp("simulate_rgb");
  const fs::path in = write_scene(tmp.path, 48, 56);
  const fs::path out = tmp.path / "rgb.png";
  auto r = run_cli("simulate " + in.string() + " " + out.string() +
                   " --wavelengths rgb --seed 3 --json --quiet");
  ASSERT_EQ(r.code, 0) << r.output;
  const json j = parse_json(r.output);
  ASSERT_EQ(j["per_channel"].size(), 3u);
  const double want_nm[3] = {610, 525, 465};
  for (int c = 0; c < 3; ++c) {
    const json& ch = j["per_channel"][std::size_t(c)];
    EXPECT_NEAR(ch["wavelength_nm"].get<double>(), want_nm[c], 1e-6);
    EXPECT_NEAR(ch["nyquist"].get<double>(), want_nm[c] * 1e-9 * 1.6 / (2 * 0.2 * 3.45e-6), 1e-6);
  }
  // D/r0 ∝ λ^(-6/5): blue sees the strongest turbulence.
  EXPECT_GT(j["per_channel"][2]["d_over_r0"].get<double>(),
            j["per_channel"][0]["d_over_r0"].get<double>() * 1.3);
  EXPECT_TRUE(fs::exists(out));
  // Two wavelengths for three channels, and no number at all: exit 2, naming the option.
  r = run_cli("simulate " + in.string() + " " + (tmp.path / "x.png").string() +
              " --wavelengths 610,525 --quiet");
  EXPECT_NE(r.code, 0);
  EXPECT_NE(r.output.find("wavelength"), std::string::npos) << r.output;
  r = run_cli("simulate " + in.string() + " " + (tmp.path / "x.png").string() +
              " --wavelengths red --quiet");
  EXPECT_EQ(r.code, 2) << r.output;
  EXPECT_NE(r.output.find("--wavelengths"), std::string::npos) << r.output;
  // A wavelength no shipped model samples at: the error names the channel and the fix.
  r = run_cli("simulate " + in.string() + " " + (tmp.path / "x.png").string() +
              " --wavelengths 700,525,465 --quiet");
  EXPECT_EQ(r.code, 1) << r.output;
  EXPECT_NE(r.output.find("channel 0"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("sim-train"), std::string::npos) << r.output;
  EXPECT_FALSE(fs::exists(tmp.path / "x.png"));
}

TEST(CliDemoTurbulence, SmallStudyWritesEveryOutput) {
  TempDir tmp("demo");
  const fs::path out = tmp.path / "demo";
  auto r = run_cli("demo-turbulence --out " + out.string() +
                   " --photos 1 --frames 1 --video-frames 2 --width 320 --json --quiet");
  ASSERT_EQ(r.code, 0) << r.output;
  const json j = parse_json(r.output);
  ASSERT_EQ(j["strengths"].size(), 3u);
  EXPECT_GT(j["faces"].get<int>(), 0);
  // Recognition degrades with turbulence: strong is no better than weak.
  EXPECT_LE(j["strengths"][2]["rank1_of_all"].get<double>(),
            j["strengths"][0]["rank1_of_all"].get<double>());
  EXPECT_GE(j["strengths"][2]["mean_descriptor_distance"].get<double>(),
            j["strengths"][0]["mean_descriptor_distance"].get<double>());
  for (const char* f : {"montage.png", "vtest_strong.avi", "results.json", "report.md"})
    EXPECT_TRUE(fs::exists(out / f)) << f;
  // Existing outputs are kept without --force; a missing video is a clear error.
  r = run_cli("demo-turbulence --out " + out.string() +
              " --photos 1 --frames 1 --video-frames 1 --width 320 --quiet");
  EXPECT_EQ(r.code, 2);
  EXPECT_NE(r.output.find("--force"), std::string::npos) << r.output;
  r = run_cli("demo-turbulence --out " + out.string() + " --video /nonexistent.avi --quiet");
  EXPECT_EQ(r.code, 2);
  EXPECT_NE(r.output.find("/nonexistent.avi is missing"), std::string::npos) << r.output;
}

TEST(CliWave, ImagesASceneThroughTheReference) {
  TempDir tmp("wave");
  const fs::path in = write_scene(tmp.path, 40, 48);
  const fs::path out = tmp.path / "wave.png";
  auto r = run_cli("wave " + in.string() + " " + out.string() +
                   " --grid 64 --screens 3 --source-step 24 --json --quiet");
  ASSERT_EQ(r.code, 0) << r.output;
  const json j = parse_json(r.output);
  EXPECT_EQ(j["sources"][0], 3);
  EXPECT_EQ(j["sources"][1], 3);
  const cv::Mat a = cv::imread(in.string()), b = cv::imread(out.string());
  ASSERT_FALSE(b.empty());
  EXPECT_GT(mean_abs_diff(a, b), 2.0);
  // FFTW on the CPU, parameters from a YAML file equal to the default preset:
  // the same image (the backends agree to float rounding; 8-bit output).
  std::ofstream(tmp.path / "cfg.yaml") << "preset: moderate\n";
  const fs::path out_fftw = tmp.path / "wave_fftw.png";
  r = run_cli("wave " + in.string() + " " + out_fftw.string() + " --config " +
              (tmp.path / "cfg.yaml").string() +
              " --grid 64 --screens 3 --source-step 24 --fft fftw --json --quiet");
  ASSERT_EQ(r.code, 0) << r.output;
  EXPECT_EQ(parse_json(r.output)["fft"], "fftw");
  const cv::Mat c = cv::imread(out_fftw.string());
  ASSERT_FALSE(c.empty());
  EXPECT_LT(mean_abs_diff(b, c), 0.05);
  std::ofstream(tmp.path / "clip.avi") << "a video";
  r = run_cli("wave " + (tmp.path / "clip.avi").string() + " " + out.string() + " --force");
  EXPECT_EQ(r.code, 2);
  EXPECT_NE(r.output.find("single frames"), std::string::npos) << r.output;
  r = run_cli("wave " + in.string() + " " + (tmp.path / "o.png").string() + " --grid 61");
  EXPECT_EQ(r.code, 2) << r.output;
  EXPECT_FALSE(fs::exists(tmp.path / "o.png"));
}

TEST(CliSimValidate, QuickTablePasses) {
  auto r = run_cli("sim-validate --quick --no-psf --json --quiet");
  ASSERT_EQ(r.code, 0) << r.output;
  const json j = parse_json(r.output);
  EXPECT_EQ(j["failed"], 0);
  EXPECT_EQ(j["checks"].size(), 10u);
  r = run_cli("sim-validate --fields 1");
  EXPECT_EQ(r.code, 2) << r.output;
}

TEST(CliBenchSim, ReportsFramesPerSecondAndSpeedup) {
  TempDir tmp("bench_sim");
  const fs::path out = tmp.path / "bench.json";
  auto r = run_cli("bench sim --sizes 64 --frames 1 --wave-step 32 --wave-grid 64 --json-file " +
                   out.string());
  ASSERT_EQ(r.code, 0) << r.output;
  std::ifstream f(out);
  const json j = json::parse(f, nullptr, false);
  ASSERT_EQ(j["sizes"].size(), 3u);  // grey, colour at one wavelength, colour at three
  EXPECT_EQ(j["sizes"][2]["wavelengths"], 3);
  for (const auto& e : j["sizes"]) {
    EXPECT_GT(e["fps"].get<double>(), 0);
    EXPECT_GT(e["speedup_vs_wave_same_device"].get<double>(), 0);
    EXPECT_GT(e["speedup_vs_wave_fftw"].get<double>(), 0);
    // Where the frame's time goes, stage by stage, and the image I/O.
    for (const char* stage : {"fields", "warp", "p2s", "blur", "image_io"}) {
      EXPECT_GT(e["stages_seconds"][stage].get<double>(), 0) << stage;
    }
  }
  EXPECT_NE(r.output.find("where a frame's time goes"), std::string::npos) << r.output;
  r = run_cli("bench sim --preset hurricane");
  EXPECT_EQ(r.code, 2);
}

}  // namespace
