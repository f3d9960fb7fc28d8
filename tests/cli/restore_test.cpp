// `vkjr2 restore-train` and `vkjr2 restore` as a user runs them, on a tiny
// network and 16² clips (the shipped training is a documented command).
#include <gtest/gtest.h>
#include <nlohmann/json.hpp>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/videoio.hpp>

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
using vkjr2::test::parse_json;
using vkjr2::test::run_cli;
using vkjr2::test::TempDir;

// Four textured 40×36 images: 3 to train on, every 4th (the first) held out.
fs::path write_images(const fs::path& dir) {
  fs::path images = dir / "images";
  fs::create_directories(images);
  for (int i = 0; i < 4; ++i) {
    cv::Mat img(36, 40, CV_8UC3);
    for (int y = 0; y < 36; ++y)
      for (int x = 0; x < 40; ++x) {
        const auto v = static_cast<unsigned char>(((x / (3 + i) + y / 4) % 2) ? 210 : 30 + 9 * x);
        img.at<cv::Vec3b>(y, x) = {v, static_cast<unsigned char>(255 - v),
                                   static_cast<unsigned char>(7 * y + 40 * i)};
      }
    cv::imwrite((images / ("img" + std::to_string(i) + ".png")).string(), img);
  }
  return images;
}

const std::string kTiny =
    " --frames 2 --width 4 --enc-blocks 1 --dec-blocks 1 --middle-blocks 0 --crop 16 --batch 2"
    " --pool 3 --val-clips 2 --val-every 4 --warmup 1 --quiet";

TEST(CliRestore, TrainsResumesAndRestores) {
  TempDir tmp("cli_restore");
  const fs::path images = write_images(tmp.path);
  const fs::path model = tmp.path / "r.safetensors", log = tmp.path / "log.jsonl";
  // Two steps, stopped; then the same run resumed to three, with the batch
  // size from a YAML config.
  const fs::path config = tmp.path / "train.yaml";
  std::ofstream(config) << "batch: 2\nd-over-r0: [1, 6]\n";
  auto r = run_cli("restore-train " + model.string() + " --images " + images.string() + kTiny +
                   " --steps 2 --log " + log.string() + " --json --config " + config.string());
  ASSERT_EQ(r.code, 0) << r.output;
  json j = parse_json(r.output);
  EXPECT_EQ(j["steps"], 2);
  EXPECT_EQ(j["train_images"], 3);
  EXPECT_EQ(j["held_out_images"], 1);
  EXPECT_GT(j["psnr_degraded"].get<double>(), 5);
  ASSERT_TRUE(fs::exists(model.string() + ".ckpt"));

  fs::remove(model);
  r = run_cli("restore-train " + model.string() + " --images " + images.string() + kTiny +
              " --steps 3 --json --resume --config " + config.string());
  // --steps is part of the schedule: a resume with another count is refused.
  EXPECT_EQ(r.code, 1) << r.output;
  EXPECT_NE(r.output.find("train.steps"), std::string::npos) << r.output;

  // A clip of 5 frames from the simulator, restored by the trained model.
  const fs::path clip = tmp.path / "clip.avi", out = tmp.path / "out.png";
  ASSERT_EQ(run_cli("simulate " + (images / "img1.png").string() + " " + clip.string() +
                    " --frames 5 --quiet")
                .code,
            0);
  r = run_cli("restore-train " + model.string() + " --images " + images.string() + kTiny +
              " --steps 2 --json --resume --config " + config.string());
  ASSERT_EQ(r.code, 0) << r.output;  // nothing left to train: the checkpoint is at step 2
  r = run_cli("restore " + clip.string() + " " + out.string() + " --model " + model.string() +
              " --json --quiet");
  ASSERT_EQ(r.code, 0) << r.output;
  j = parse_json(r.output);
  EXPECT_EQ(j["results"][0]["frames_read"], 5);
  EXPECT_EQ(j["results"][0]["restored"], 1);
  const cv::Mat restored = cv::imread(out.string());
  EXPECT_EQ(restored.cols, 40);
  EXPECT_EQ(restored.rows, 36);
  // A video OUT restores every frame.
  const fs::path video = tmp.path / "out.avi";
  r = run_cli("restore " + clip.string() + " " + video.string() + " --model " + model.string() +
              " --json --quiet");
  ASSERT_EQ(r.code, 0) << r.output;
  EXPECT_EQ(parse_json(r.output)["results"][0]["restored"], 5);

  // The log holds a line per step and one per held-out score.
  std::ifstream in(log);
  int steps = 0, scores = 0;
  for (std::string line; std::getline(in, line);) {
    const json l = json::parse(line);
    steps += l.contains("loss") ? 1 : 0;
    scores += l.contains("psnr_restored") ? 1 : 0;
  }
  EXPECT_EQ(steps, 2);
  EXPECT_EQ(scores, 1);

  // The evaluation's classical and restored rows beside the degraded one, on
  // a tiny benchmark (3 identities, weak, 3 frames or 2 under the
  // sanitizers; one alignment and detector size).
  const fs::path bench = tmp.path / "bench", eval_out = tmp.path / "eval";
  const int ids = 3, frames = vkjr2::test::kSanitized ? 2 : 3;
  r = run_cli("dataset make --out " + bench.string() + " --max-identities " + std::to_string(ids) +
              " --strengths weak --frames " + std::to_string(frames) + " --quiet");
  ASSERT_EQ(r.code, 0) << r.output;
  r = run_cli("eval " + (bench / "manifest.json").string() + " --out " + eval_out.string() +
              " --method degraded,classical,restored:" + model.string() +
              " --align face_api --input-sizes 160 --resamples 20 --quiet --json");
  ASSERT_EQ(r.code, 0) << r.output;
  j = parse_json(r.output);
  ASSERT_EQ(j["rows"].size(), 3u) << r.output;
  std::vector<std::string> methods;
  for (const json& row : j["rows"]) {
    methods.push_back(row["method"].get<std::string>());
    EXPECT_EQ(row["probes"], ids);
    EXPECT_GT(row["psnr_db"]["value"].get<double>(), 10.0) << row.dump();
  }
  EXPECT_EQ(methods, (std::vector<std::string>{"degraded", "classical", "restored:r"}));

  // --faces on a probe clip: the face region is restored and blended in, the
  // rest of the frame is the input's own.
  fs::path probe;
  for (const auto& e : fs::recursive_directory_iterator(bench / "probes")) {
    if (e.path().extension() == ".avi") probe = e.path();
  }
  ASSERT_FALSE(probe.empty());
  const fs::path faces = tmp.path / "faces.png";
  r = run_cli("restore " + probe.string() + " " + faces.string() + " --model " + model.string() +
              " --faces --face-margin 0 --frame 0 --json --quiet");
  ASSERT_EQ(r.code, 0) << r.output;
  j = parse_json(r.output)["results"][0];
  EXPECT_GE(j["face_regions"].get<int>(), 1) << r.output;
  cv::VideoCapture cap(probe.string());
  cv::Mat first;
  ASSERT_TRUE(cap.read(first));
  const cv::Mat pasted = cv::imread(faces.string());
  ASSERT_EQ(pasted.size(), first.size());
  EXPECT_EQ(pasted.at<cv::Vec3b>(0, 0), first.at<cv::Vec3b>(0, 0));
  EXPECT_EQ(pasted.at<cv::Vec3b>(first.rows - 1, first.cols - 1),
            first.at<cv::Vec3b>(first.rows - 1, first.cols - 1));
  EXPECT_GT(cv::norm(pasted, first, cv::NORM_L1), 0.0);
  r = run_cli("restore " + probe.string() + " " + faces.string() +
              " --faces --detector-size 100 --force");
  EXPECT_EQ(r.code, 2) << r.output;
  EXPECT_NE(r.output.find("multiple of 32"), std::string::npos) << r.output;
}

TEST(CliRestore, BadInputsAreClearErrors) {
  TempDir tmp("cli_restore_bad");
  const fs::path images = write_images(tmp.path);
  auto r = run_cli("restore-train " + (tmp.path / "r.safetensors").string() + " --images " +
                   images.string() + " --crop 20 --quiet");
  EXPECT_EQ(r.code, 2) << r.output;
  EXPECT_NE(r.output.find("--crop"), std::string::npos) << r.output;
  r = run_cli("restore-train " + (tmp.path / "r.safetensors").string() + " --images " +
              images.string() + " --crop 64 --quiet");
  EXPECT_EQ(r.code, 2) << r.output;
  EXPECT_NE(r.output.find("lower --crop"), std::string::npos) << r.output;
  // A blur model is not a restorer.
  const fs::path clip = tmp.path / "clip.avi";
  ASSERT_EQ(run_cli("simulate " + (images / "img1.png").string() + " " + clip.string() +
                    " --frames 2 --quiet")
                .code,
            0);
  const fs::path p2s = fs::path(VKJR2_SOURCE_DIR) / "artifacts" / "p2s_default.safetensors";
  r = run_cli("restore " + clip.string() + " " + (tmp.path / "o.png").string() + " --model " +
              p2s.string());
  EXPECT_EQ(r.code, 1) << r.output;
  EXPECT_NE(r.output.find("p2s_default.safetensors"), std::string::npos) << r.output;
  r = run_cli("restore " + clip.string() + " " + (tmp.path / "o.txt").string() + " --model " +
              p2s.string());
  EXPECT_EQ(r.code, 2) << r.output;
  r = run_cli("restore " + (tmp.path / "missing.avi").string() + " " +
              (tmp.path / "o.png").string());
  EXPECT_EQ(r.code, 2) << r.output;
  EXPECT_NE(r.output.find("missing.avi"), std::string::npos) << r.output;
  // The study's commands: a blur model is not a clip set; absurd options.
  r = run_cli("restore-score " + p2s.string());
  EXPECT_EQ(r.code, 1) << r.output;
  EXPECT_NE(r.output.find("not a clip set"), std::string::npos) << r.output;
  r = run_cli("restore-train " + (tmp.path / "r.safetensors").string() + " --images " +
              images.string() + " --explicit -1 --quiet");
  EXPECT_EQ(r.code, 2) << r.output;
  EXPECT_NE(r.output.find("--explicit"), std::string::npos) << r.output;
  r = run_cli("restore-train " + (tmp.path / "r.safetensors").string() + " --images " +
              images.string() + " --blur-model " + (tmp.path / "none.safetensors").string() +
              " --quiet");
  EXPECT_EQ(r.code, 2) << r.output;
  EXPECT_NE(r.output.find("none.safetensors"), std::string::npos) << r.output;
  r = run_cli("wave-clips " + (tmp.path / "w.safetensors").string() + " --images " +
              images.string() + " --clips 0 --quiet");
  EXPECT_EQ(r.code, 2) << r.output;
  EXPECT_NE(r.output.find("--clips"), std::string::npos) << r.output;
  EXPECT_FALSE(fs::exists(tmp.path / "w.safetensors"));
}

// Explicit training on the simpler simulator, a wave-optics clip set and
// the score of the trained model on it (study 2 in miniature).
TEST(CliRestore, ExplicitTrainingAndTheWaveOpticsScore) {
  TempDir tmp("cli_restore_study");
  const fs::path images = write_images(tmp.path);
  const fs::path model = tmp.path / "e.safetensors", log = tmp.path / "log.jsonl";
  const fs::path p2s = fs::path(VKJR2_SOURCE_DIR) / "artifacts" / "p2s_default.safetensors";
  auto r = run_cli("restore-train " + model.string() + " --images " + images.string() + kTiny +
                   " --steps 1 --explicit 0.5 --uncorrelated-high-order --blur-model " +
                   p2s.string() + " --log " + log.string() + " --json");
  ASSERT_EQ(r.code, 0) << r.output;
  std::ifstream in(log);
  std::string first;
  std::getline(in, first);
  EXPECT_GT(json::parse(first)["consistency"].get<double>(), 0) << first;

  const fs::path clips = tmp.path / "wave.safetensors";
  r = run_cli("wave-clips " + clips.string() + " --images " + images.string() +
              " --val-every 4 --clips 1 --frames 2 --size 24 --screens 2 --quiet --json");
  ASSERT_EQ(r.code, 0) << r.output;
  EXPECT_EQ(parse_json(r.output)["clips"], 1);
  const fs::path scores = tmp.path / "scores.json";
  r = run_cli("restore-score " + clips.string() + " --model " + model.string() +
              " --resamples 20 --out " + scores.string());
  ASSERT_EQ(r.code, 0) << r.output;
  EXPECT_NE(r.output.find("gain over degraded"), std::string::npos) << r.output;
  std::ifstream sf(scores);
  const json j = json::parse(sf);
  ASSERT_EQ(j["rows"].size(), 3u);
  EXPECT_EQ(j["rows"][2]["method"], "e");
  EXPECT_EQ(j["source"], "wave-optics");
  EXPECT_GT(j["rows"][0]["psnr_db"]["value"].get<double>(), 5.0);
}

}  // namespace
