// `vkjr2 demo` as a user runs it, at a tiny size: the benchmark made and
// the four configurations evaluated, the report, the montage and the
// restored video; existing outputs and a missing artifact are clear errors
// before any work.
#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <filesystem>
#include <fstream>
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

TEST(CliDemo, RunsTheStudyAndWritesItsReport) {
  TempDir tmp("cli_demo");
  const fs::path out = tmp.path / "demo";
  const std::string cmd = "demo --out " + out.string() +
                          " --identities 3 --frames 10 --clip-size 96 --face-px 64 --montage 2 "
                          "--resamples 20 --quiet --json";
  auto r = run_cli(cmd);
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
