// `vkjr2 cotrain` as a user runs it: a tiny benchmark and a tiny restorer,
// two steps, resumed to three with the same log; the model it writes is a
// restorer `vkjr2 restore` reads; bad options are usage errors before any
// work.
#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <cstdint>
#include <filesystem>
#include <fstream>
#include <map>
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

// A tiny benchmark (3 identities, weak, 2 frames) and a tiny teacher (a
// restorer of one training step on its clean clips) in `dir`; returns the
// options every cotrain run of the tests shares (the window and batch from a
// config file).
std::string tiny_setup(const fs::path& dir) {
  const fs::path bench = dir / "bench";
  auto r = run_cli("dataset make --out " + bench.string() +
                   " --max-identities 3 --strengths weak --frames 2 --quiet");
  EXPECT_EQ(r.code, 0) << r.output;
  const fs::path images = dir / "images", teacher = dir / "teacher.safetensors";
  fs::create_directories(images);
  for (const auto& e : fs::recursive_directory_iterator(bench)) {
    if (e.path().extension() == ".png" && !fs::exists(images / e.path().filename())) {
      fs::copy_file(e.path(), images / e.path().filename());
    }
  }
  r = run_cli("restore-train " + teacher.string() + " --images " + images.string() +
              " --val-every 2 --frames 2 --width 4 --enc-blocks 1 --dec-blocks 1 "
              "--middle-blocks 0 --crop 16 --batch 2 --pool 2 --val-clips 1 --steps 1 --quiet");
  EXPECT_EQ(r.code, 0) << r.output;
  const fs::path config = dir / "co.yaml";
  std::ofstream(config) << "window: 64\nbatch: 2\n";
  return " --benchmark " + (bench / "manifest.json").string() + " --pretrained " +
         teacher.string() +
         " --pool 2 --val-clips 2 --warmup 1 --lambda 100 --eval-every 2"
         " --checkpoint-every 1 --quiet --json --config " +
         config.string();
}

TEST(CliCotrain, TrainsResumesAndWritesARestorer) {
  TempDir tmp("cli_cotrain");
  const fs::path bench = tmp.path / "bench";
  const fs::path model = tmp.path / "co.safetensors", log = tmp.path / "co.jsonl";
  const std::string common = tiny_setup(tmp.path) + " --log " + log.string();
  ASSERT_FALSE(HasFailure());
  auto r = run_cli("cotrain " + model.string() + common + " --steps 2");
  ASSERT_EQ(r.code, 0) << r.output;
  json j = parse_json(r.output);
  EXPECT_EQ(j["steps"], 2);
  EXPECT_EQ(j["identities"], 3);
  EXPECT_GT(j["student"]["psnr"].get<double>(), 10.0) << r.output;
  // Resumed with another --steps (another schedule): refused, naming it
  // (not under the sanitizers: the test's time); the same settings go on.
  if (!vkjr2::test::kSanitized) {
    r = run_cli("cotrain " + model.string() + common + " --steps 3 --resume --force");
    EXPECT_EQ(r.code, 1) << r.output;
    EXPECT_NE(r.output.find("cotrain.steps"), std::string::npos) << r.output;
  }
  fs::remove(model);
  r = run_cli("cotrain " + model.string() + common + " --steps 2 --resume");
  ASSERT_EQ(r.code, 0) << r.output;

  std::ifstream in(log);
  int configs = 0, steps = 0, scores = 0;
  for (std::string line; std::getline(in, line);) {
    const json l = json::parse(line);
    configs += l.contains("config") ? 1 : 0;
    if (l.contains("loss")) {
      ++steps;
      EXPECT_TRUE(l.contains("stages") && l["stages"].contains("backward")) << line;
      EXPECT_GT(l["recognition"].get<double>(), 0.0) << line;
    }
    scores += l.contains("student") ? 1 : 0;
  }
  EXPECT_EQ(configs, 2);  // one per run (the refused one stopped before its log)
  EXPECT_EQ(steps, 2);
  EXPECT_EQ(scores, 2);  // after step 2, and again on the resume that found the run done

  // The co-trained model is a restorer.
  fs::path probe;
  for (const auto& e : fs::recursive_directory_iterator(bench / "probes")) {
    if (e.path().extension() == ".avi") probe = e.path();
  }
  r = run_cli("restore " + probe.string() + " " + (tmp.path / "out.png").string() + " --model " +
              model.string() + " --quiet");
  EXPECT_EQ(r.code, 0) << r.output;
}

TEST(CliCotrain, AlignFirstModelsRestoreTheAlignedCrop) {
  TempDir tmp("cli_cotrain_af");
  const fs::path bench = tmp.path / "bench";
  const std::string common = tiny_setup(tmp.path) + " --log " + (tmp.path / "af.jsonl").string();
  ASSERT_FALSE(HasFailure());
  // An align-first model restores the aligned crop in the evaluation, which
  // needs the similarity alignment alone.
  const fs::path aligned = tmp.path / "af.safetensors";
  auto r = run_cli("cotrain " + aligned.string() + common + " --steps 1 --order align-first");
  ASSERT_EQ(r.code, 0) << r.output;
  const std::string eval = "eval " + (bench / "manifest.json").string() + " --out " +
                           (tmp.path / "eval").string() +
                           " --method degraded,restored:" + aligned.string() +
                           " --input-sizes 160 --resamples 20 --quiet --json";
  r = run_cli(eval + " --align face_api,similarity");
  EXPECT_EQ(r.code, 2) << r.output;
  EXPECT_NE(r.output.find("--align similarity"), std::string::npos) << r.output;
  r = run_cli(eval + " --align similarity");
  ASSERT_EQ(r.code, 0) << r.output;
  const json j = parse_json(r.output);
  ASSERT_EQ(j["rows"].size(), 2u) << r.output;
  const json& af = j["rows"][1];
  EXPECT_EQ(af["method"], "restored:af");
  EXPECT_GT(af["psnr_db"]["value"].get<double>(), 10.0) << af.dump();
  EXPECT_NE(af["psnr_db"]["value"], j["rows"][0]["psnr_db"]["value"]);  // crops, not frames
}

// The benchmark of a co-training step runs and writes its JSON (the peer
// left out: timings are bench/'s business, not a test's).
TEST(CliBenchCotrain, TimesEveryStageAndTheStep) {
  TempDir tmp("bench_cotrain");
  const fs::path out = tmp.path / "bench.json";
  auto r = run_cli("bench cotrain --no-torch --batch 2 --window 64 --repeat 1 --json-file " +
                   out.string());
  ASSERT_EQ(r.code, 0) << r.output;
  std::ifstream f(out);
  const json j = json::parse(f, nullptr, false);
  ASSERT_TRUE(j.is_object()) << r.output;
  const json& ours = j["vkjr2"];
  EXPECT_GT(ours["step_s"].get<double>(), 0.0);
  ASSERT_TRUE(ours["stages_s"].is_object()) << ours.dump();
  EXPECT_GE(ours["stages_s"].size(), 5u);
  for (const auto& [stage, seconds] : ours["stages_s"].items()) {
    EXPECT_GT(seconds.get<double>(), 0.0) << stage;
  }
  r = run_cli("bench cotrain --window 60 --no-torch");
  EXPECT_EQ(r.code, 2) << r.output;
}

TEST(CliCotrain, BadOptionsAreUsageErrors) {
  TempDir tmp("cli_cotrain_bad");
  const fs::path out = tmp.path / "co.safetensors", missing = tmp.path / "none.json";
  auto r = run_cli("cotrain " + out.string() + " --benchmark " + missing.string());
  EXPECT_EQ(r.code, 2) << r.output;
  EXPECT_NE(r.output.find("none.json"), std::string::npos) << r.output;
  const fs::path manifest = tmp.path / "manifest.json";
  std::ofstream(manifest) << "{}";
  for (const auto& [args, word] :
       std::vector<std::pair<std::string, std::string>>{{"--lambda -1", "--lambda"},
                                                        {"--order restore-last", "restore-last"},
                                                        {"--layers top", "top"},
                                                        {"--batch 1", "--batch"},
                                                        {"--window 100", "--window"}}) {
    r = run_cli("cotrain " + out.string() + " --benchmark " + manifest.string() + " " + args);
    EXPECT_EQ(r.code, 2) << args << "\n" << r.output;
    EXPECT_NE(r.output.find(word), std::string::npos) << args << "\n" << r.output;
  }
  // A config file's keys are the options' long names; another key is named.
  const fs::path config = tmp.path / "co.yaml";
  std::ofstream(config) << "windw: 64\n";
  r = run_cli("cotrain " + out.string() + " --benchmark " + manifest.string() + " --config " +
              config.string());
  EXPECT_EQ(r.code, 2) << r.output;
  EXPECT_NE(r.output.find("'windw' is not an option"), std::string::npos) << r.output;
  EXPECT_FALSE(fs::exists(out));
}

// The tensor shapes a safetensors file's header declares, by name.
std::map<std::string, std::vector<std::int64_t>> safetensors_shapes(const fs::path& path) {
  std::ifstream in(path, std::ios::binary);
  std::uint64_t n = 0;
  in.read(reinterpret_cast<char*>(&n), sizeof n);
  std::string header(n, '\0');
  in.read(header.data(), std::streamsize(n));
  std::map<std::string, std::vector<std::int64_t>> shapes;
  const json parsed = json::parse(header);
  for (const auto& [name, entry] : parsed.items()) {
    if (name != "__metadata__") shapes[name] = entry["shape"].get<std::vector<std::int64_t>>();
  }
  return shapes;
}

// Unpaired co-training makes its wave-optics set (here one clip of two frames
// per identity, coarse point sources) and trains on it.
TEST(CliCotrain, UnpairedMakesOneWaveClipPerIdentity) {
  TempDir tmp("cli_cotrain_unpaired");
  const std::string common = tiny_setup(tmp.path);
  ASSERT_FALSE(HasFailure());
  const fs::path wave = tmp.path / "wave.safetensors", model = tmp.path / "un.safetensors";
  auto r = run_cli("cotrain " + model.string() + common + " --steps 1 --unpaired " + wave.string() +
                   " --unpaired-per-identity 1 --unpaired-frames 2 --unpaired-source-step 80"
                   " --d-over-r0 1 2");
  ASSERT_EQ(r.code, 0) << r.output;
  const json j = parse_json(r.output);
  EXPECT_EQ(j["identities"], 3);
  EXPECT_EQ(j["training_clips"].get<int>(), 3) << r.output;
  EXPECT_LE(j["faceless_clips"].get<int>(), 1) << r.output;
  const auto shapes = safetensors_shapes(wave);
  ASSERT_TRUE(shapes.contains("degraded")) << wave;
  const std::vector<std::int64_t> want{3, 2, 3, 160, 160};
  EXPECT_EQ(shapes.at("degraded"), want);
  r = run_cli("cotrain " + model.string() + common + " --steps 1 --unpaired " + wave.string() +
              " --unpaired-per-identity -1 --force");
  EXPECT_EQ(r.code, 2) << r.output;
  EXPECT_NE(r.output.find("--unpaired-per-identity"), std::string::npos) << r.output;
  // Fewer frames than the restorer reads: refused before the set is made.
  const fs::path short_set = tmp.path / "short.safetensors";
  r = run_cli("cotrain " + model.string() + common + " --steps 1 --unpaired " + short_set.string() +
              " --unpaired-frames 1 --force");
  EXPECT_EQ(r.code, 2) << r.output;
  EXPECT_NE(r.output.find("--unpaired-frames 2"), std::string::npos) << r.output;
  EXPECT_FALSE(fs::exists(short_set));
}

}  // namespace
