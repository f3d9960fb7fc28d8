// `vkjr2 estimate` and `vkjr2 estimate-train` as a user runs them: a
// calibration fitted on a tiny benchmark's val probes, the test probes
// estimated with it (errors against their true D/r0), one video on its own,
// and bad input as clear errors.
#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <string>

#include "support/cli_checks.hpp"
#include "support/cli_files.hpp"
#include "support/run_cli.hpp"

namespace {

namespace fs = std::filesystem;
using nlohmann::json;
using vkjr2::test::parse_json;
using vkjr2::test::run_cli;
using vkjr2::test::TempDir;

TEST(CliEstimate, CalibratesAndEstimatesBenchmarkProbes) {
  TempDir tmp("cli_estimate");
  const fs::path bench = tmp.path / "bench", cal = tmp.path / "cal.safetensors";
  auto r = run_cli("dataset make --out " + bench.string() +
                   " --max-identities 3 --strengths weak,strong --frames 10 --clip-size 96 "
                   "--face-px 48 --quiet");
  ASSERT_EQ(r.code, 0) << r.output;
  const std::string manifest = (bench / "manifest.json").string();
  r = run_cli("estimate-train " + cal.string() + " --benchmark " + manifest + " --json");
  ASSERT_EQ(r.code, 0) << r.output;
  json j = parse_json(r.output);
  EXPECT_EQ(j["videos"], 6);  // 3 identities × 2 strengths of the val split
  EXPECT_GT(j["gain"].get<double>(), 0.0);
  EXPECT_EQ(j["cues"], "spectrum");
  EXPECT_NE(j["blur_exponent"].get<double>(), 0.0);
  EXPECT_EQ(j["exponent"].get<double>(), 0.0);
  EXPECT_TRUE(fs::exists(cal));
  // The tilt alone, and both cues; a band that is not one is a usage error
  // before any work.
  const fs::path cal_tilt = tmp.path / "cal_tilt.safetensors";
  r = run_cli("estimate-train " + cal_tilt.string() + " --benchmark " + manifest +
              " --cues tilt --json");
  ASSERT_EQ(r.code, 0) << r.output;
  EXPECT_EQ(parse_json(r.output)["cues"], "tilt");
  EXPECT_EQ(parse_json(r.output)["blur_exponent"].get<double>(), 0.0);
  const fs::path cal_both = tmp.path / "cal_both.safetensors";
  r = run_cli("estimate-train " + cal_both.string() + " --benchmark " + manifest +
              " --cues tilt+spectrum --json");
  ASSERT_EQ(r.code, 0) << r.output;
  EXPECT_EQ(parse_json(r.output)["cues"], "tilt+spectrum");
  r = run_cli("estimate-train " + (tmp.path / "bad.safetensors").string() + " --benchmark " +
              manifest + " --band 0.3 0.2");
  EXPECT_EQ(r.code, 2) << r.output;
  EXPECT_NE(r.output.find("spectral band"), std::string::npos) << r.output;
  EXPECT_FALSE(fs::exists(tmp.path / "bad.safetensors"));
  // Refused over an existing file without --force, before any work.
  r = run_cli("estimate-train " + cal.string() + " --benchmark " + manifest);
  EXPECT_EQ(r.code, 2) << r.output;

  const fs::path out = tmp.path / "test.json";
  r = run_cli("estimate --benchmark " + manifest + " --calibration " + cal.string() +
              " --json --quiet --out " + out.string());
  ASSERT_EQ(r.code, 0) << r.output;
  j = parse_json(r.output);
  ASSERT_EQ(j["videos"].size(), 6u);
  for (const json& v : j["videos"]) {
    EXPECT_GT(v["d_over_r0"].get<double>(), 0.0) << v.dump();
    EXPECT_NEAR(v["r0_m"].get<double>() * v["d_over_r0"].get<double>(), 0.2, 1e-9) << v.dump();
    EXPECT_GT(v["true_d_over_r0"].get<double>(), 0.0) << v.dump();
    EXPECT_EQ(v["frames"], 10);
    EXPECT_GT(v["spectral_fluctuation"].get<double>(), 0.0) << v.dump();
    EXPECT_EQ(v["spectral_tiles"], 4) << v.dump();          // 64² tiles of a 96² frame
    EXPECT_FALSE(v.contains("raw_d_over_r0")) << v.dump();  // the tilt is not measured
  }
  EXPECT_EQ(j["cues"], "spectrum");
  // weak, strong and all, each with its error statistics.
  ASSERT_EQ(j["errors"].size(), 3u) << j.dump();
  EXPECT_EQ(j["errors"][2]["group"], "all");
  std::ifstream written(out);
  EXPECT_EQ(json::parse(written), j);

  // The device registration: a calibration of its own, used as it was fitted.
  const fs::path cal_lk = tmp.path / "cal_lk.safetensors";
  r = run_cli("estimate-train " + cal_lk.string() + " --benchmark " + manifest +
              " --cues tilt --registration lk --iterations 3 --passes 1 --json");
  ASSERT_EQ(r.code, 0) << r.output;
  r = run_cli("estimate-train " + (tmp.path / "lk_spectrum.safetensors").string() +
              " --benchmark " + manifest + " --registration lk");
  EXPECT_EQ(r.code, 2) << r.output;  // the spectrum alone registers nothing
  EXPECT_NE(r.output.find("--cues"), std::string::npos) << r.output;
  r = run_cli("estimate --benchmark " + manifest + " --calibration " + cal_lk.string() +
              " --json --quiet");
  ASSERT_EQ(r.code, 0) << r.output;
  EXPECT_EQ(parse_json(r.output)["videos"].size(), 6u);

  // One video: its estimate alone; the stronger turbulence reads stronger.
  double weak = 0, strong = 0;
  for (const char* s : {"weak", "strong"}) {
    fs::path video;
    for (const auto& e : fs::directory_iterator(bench / "probes" / "test" / s)) {
      if (e.path().extension() == ".avi") video = e.path();
    }
    r = run_cli("estimate " + video.string() + " --calibration " + cal.string() + " --json");
    ASSERT_EQ(r.code, 0) << r.output;
    const json one = parse_json(r.output);
    (std::string(s) == "weak" ? weak : strong) += one["d_over_r0"].get<double>();
    // The shipped calibration (artifacts/turbulence_estimator.safetensors)
    // measures the same cue with the same options.
    r = run_cli("estimate " + video.string() + " --json");
    ASSERT_EQ(r.code, 0) << r.output;
    EXPECT_DOUBLE_EQ(parse_json(r.output)["spectral_fluctuation"].get<double>(),
                     one["spectral_fluctuation"].get<double>());
  }
  EXPECT_GT(strong, weak);

  // The optics of --config set the pixel scale: twice the focal length halves
  // the angle of a pixel, so the same tilt in pixels is 4^(3/5) less D/r0.
  fs::path video;
  for (const auto& e : fs::directory_iterator(bench / "probes" / "test" / "strong")) {
    if (e.path().extension() == ".avi") video = e.path();
  }
  const fs::path config = tmp.path / "optics.yaml";
  std::ofstream(config) << "optics:\n  focal_length_m: 3.2\n";
  r = run_cli("estimate " + video.string() + " --raw --json");
  ASSERT_EQ(r.code, 0) << r.output;
  const double at_preset = parse_json(r.output)["raw_d_over_r0"].get<double>();
  r = run_cli("estimate " + video.string() + " --raw --json --config " + config.string());
  ASSERT_EQ(r.code, 0) << r.output;
  EXPECT_NEAR(parse_json(r.output)["raw_d_over_r0"].get<double>(), at_preset * std::pow(4.0, -0.6),
              1e-9 * at_preset);
}

TEST(CliEstimate, BadInputIsAClearError) {
  TempDir tmp("cli_estimate_bad");
  const fs::path image = vkjr2::test::write_noise_image(tmp.path / "noise.png", 64, 64);
  auto r = run_cli("estimate " + image.string() + " --raw");
  EXPECT_EQ(r.code, 2) << r.output;
  EXPECT_NE(r.output.find("is not a video"), std::string::npos) << r.output;
  r = run_cli("estimate --raw");
  EXPECT_EQ(r.code, 2) << r.output;
  EXPECT_NE(r.output.find("nothing to estimate"), std::string::npos) << r.output;
  r = run_cli("estimate " + (tmp.path / "missing.avi").string() + " --raw");
  EXPECT_EQ(r.code, 2) << r.output;
  // A flat video (one grey level, brightening) has nothing to register.
  const fs::path flat = tmp.path / "flat.avi";
  ASSERT_TRUE(vkjr2::test::write_clip(flat, cv::Mat(64, 64, CV_8UC3, cv::Scalar::all(90)), 6, 2));
  r = run_cli("estimate " + flat.string() + " --raw");
  EXPECT_EQ(r.code, 1) << r.output;
  EXPECT_NE(r.output.find("flat.avi"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("texture enough"), std::string::npos) << r.output;
  EXPECT_EQ(vkjr2::test::error_lines(r.output), 1) << r.output;
  // A truncated video: an error naming the file, no decoder noise.
  const fs::path noisy = tmp.path / "noisy.avi", cut = tmp.path / "cut.avi";
  ASSERT_TRUE(vkjr2::test::write_clip(noisy, cv::imread(image.string()), 8, 1));
  vkjr2::test::write_truncated(noisy, cut, 0.5);
  r = run_cli("estimate " + cut.string() + " --raw");
  EXPECT_EQ(r.code, 1) << r.output;
  EXPECT_NE(r.output.find("cut.avi"), std::string::npos) << r.output;
  EXPECT_FALSE(vkjr2::test::has_decoder_noise(r.output)) << r.output;
  // A calibration that is not one.
  r = run_cli("estimate " + noisy.string() + " --calibration " + image.string());
  EXPECT_EQ(r.code, 1) << r.output;
  EXPECT_NE(r.output.find("noise.png"), std::string::npos) << r.output;
  // estimate-train without videos of known strength.
  r = run_cli("estimate-train " + (tmp.path / "c.safetensors").string());
  EXPECT_EQ(r.code, 2) << r.output;
  EXPECT_NE(r.output.find("nothing to calibrate on"), std::string::npos) << r.output;
}

}  // namespace

namespace {

TEST(CliBenchEstimate, ComparesTheRegistrationsWithTheExactTilt) {
  TempDir tmp("bench_estimate");
  const fs::path out = tmp.path / "bench.json";
  auto r = run_cli(
      "bench estimate --videos 2 --strengths 2 --frames 6 --size 48 --quiet "
      "--json-file " +
      out.string());
  ASSERT_EQ(r.code, 0) << r.output;
  std::ifstream f(out);
  const json j = json::parse(f, nullptr, false);
  ASSERT_TRUE(j.is_object()) << r.output;
  ASSERT_EQ(j["results"].size(), 3u) << j.dump();
  for (const json& row : j["results"]) {
    EXPECT_GT(row["value"].get<double>(), 0.0) << row.dump();
    EXPECT_GT(row["peer_value"].get<double>(), 0.0) << row.dump();
  }
  ASSERT_EQ(j["videos"].size(), 2u);
  EXPECT_GT(j["videos"][0]["exact_variance_px2"].get<double>(), 0.0);
  r = run_cli("bench estimate --videos 1");
  EXPECT_EQ(r.code, 2) << r.output;
}

}  // namespace
