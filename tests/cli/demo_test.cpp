// `vkjr2 demo` as a user runs it, at a tiny size: the benchmark made and
// the four configurations evaluated, the report, the montage and the
// restored video; existing outputs and a missing artifact are clear errors
// before any work.
#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <cstdint>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <sstream>
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

// A copy of a safetensors file with one metadata value set.
void copy_with_metadata(const fs::path& from, const fs::path& to, const std::string& key,
                        const std::string& value) {
  std::ifstream in(from, std::ios::binary);
  std::uint64_t n = 0;
  in.read(reinterpret_cast<char*>(&n), sizeof n);
  std::string header(n, '\0');
  in.read(header.data(), std::streamsize(n));
  const std::string data((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  json h = json::parse(header);
  h["__metadata__"][key] = value;
  std::string text = h.dump();
  text.append((8 - text.size() % 8) % 8, ' ');  // the data stays 8-byte aligned
  const std::uint64_t m = text.size();
  std::ofstream o(to, std::ios::binary);
  o.write(reinterpret_cast<const char*>(&m), sizeof m);
  o << text << data;
}

TEST(CliDemo, RunsTheStudyAndWritesItsReport) {
  TempDir tmp("cli_demo");
  const fs::path out = tmp.path / "demo";
  const std::string cmd = "demo --out " + out.string() +
                          " --identities 3 --frames 10 --clip-size 96 --face-px 64 --montage 2 "
                          "--resamples 20 --quiet --json --cotrain-study ";
  auto r = run_cli(cmd + (tmp.path / "no_study").string());
  ASSERT_EQ(r.code, 0) << r.output;
  const json j = parse_json(r.output);
  EXPECT_EQ(j["identities"], 3);
  // 3 strengths × degraded, + restoration, + gate, + co-optimization.
  ASSERT_EQ(j["table"].size(), 12u) << j.dump();
  for (const json& row : j["table"]) {
    EXPECT_GT(row["seconds_per_probe"]["value"].get<double>(), 0.0) << row.dump();
    EXPECT_EQ(row["configuration"] == "+ gate", row["gate"].is_object()) << row.dump();
  }
  for (const char* f :
       {"report.md", "results.json", "montage.png", "restored_probe.avi", "eval/results.json",
        "eval/rank_change.png", "eval/roc.png", "bench/manifest.json"}) {
    EXPECT_TRUE(fs::exists(out / f)) << f;
  }
  std::ifstream in(out / "report.md");
  std::stringstream report;
  report << in.rdbuf();
  EXPECT_NE(report.str().find("| strong | + gate |"), std::string::npos) << report.str();
  EXPECT_NE(report.str().find("At strong turbulence"), std::string::npos) << report.str();
  EXPECT_NE(report.str().find("No λ trade-off plot"), std::string::npos) << report.str();
  EXPECT_TRUE(j["lambda_plot"].empty()) << j.dump();

  // With an evaluated λ sweep of a co-training study (here the shipped
  // co-optimized restorer twice, the second marked λ = 100), its trade-off
  // is drawn (not under the sanitizers: a second study's time).
  if (!vkjr2::test::kSanitized) {
    const fs::path study = tmp.path / "study";
    fs::create_directories(study);
    const fs::path shipped =
        fs::path(VKJR2_SOURCE_DIR) / "artifacts" / "restorer_cotrained.safetensors";
    fs::copy_file(shipped, study / "lambda_10.safetensors");
    copy_with_metadata(shipped, study / "lambda_100.safetensors", "cotrain.lambda", "100");
    r = run_cli("eval " + (out / "bench" / "manifest.json").string() + " --out " +
                (study / "eval").string() + " --split test --align similarity --method restored:" +
                (study / "lambda_10.safetensors").string() + ",restored:" +
                (study / "lambda_100.safetensors").string() + " --resamples 20 --quiet");
    ASSERT_EQ(r.code, 0) << r.output;
    r = run_cli(cmd + study.string() + " --force");
    ASSERT_EQ(r.code, 0) << r.output;
    const json again = parse_json(r.output);
    EXPECT_EQ(again["lambda_plot"], json::parse("[10, 100]")) << again.dump();
    EXPECT_TRUE(fs::exists(out / "lambda_psnr.png"));
    EXPECT_TRUE(fs::exists(out / "lambda_recognition.png"));
  }

  // Again without --force: refused before any work.
  r = run_cli("demo --out " + out.string() + " --identities 3 --frames 10 --quiet");
  EXPECT_EQ(r.code, 2) << r.output;
  EXPECT_NE(r.output.find("--force"), std::string::npos) << r.output;

  // A missing artifact, named, before any work.
  const fs::path empty = tmp.path / "no_artifacts";
  fs::create_directories(empty);
  r = run_cli("demo --out " + (tmp.path / "d2").string(), "VKJR2_ARTIFACT_DIR=" + empty.string());
  EXPECT_EQ(r.code, 2) << r.output;
  EXPECT_NE(r.output.find("restorer_default.safetensors"), std::string::npos) << r.output;
  EXPECT_FALSE(fs::exists(tmp.path / "d2"));
}

}  // namespace
