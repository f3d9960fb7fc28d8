// `vkjr2 bench` as a user runs it: the launcher, and `bench kernels` end to end
// (`bench sim`: simulate_test.cpp).
#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

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

// One small case (warp 512², about a second): the table, the printed JSON and
// the JSON file, each row against its peer.
TEST(CliBenchKernels, OneCaseTableAndJson) {
  TempDir tmp("bench_kernels");
  const fs::path file = tmp.path / "kernels.json";
  const auto r = run_cli("bench kernels --only warp --json --json-file " + file.string());
  ASSERT_EQ(r.code, 0) << r.output;
  EXPECT_NE(r.output.find("cv::remap"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("ratio"), std::string::npos) << r.output;
  std::ifstream f(file);
  const json written = json::parse(f, nullptr, false);
  ASSERT_TRUE(written.is_object()) << r.output;
  const json printed = parse_json(r.output.substr(r.output.find("\n{")));
  EXPECT_EQ(printed, written);
  ASSERT_EQ(written["results"].size(), 1u);
  const json& row = written["results"][0];
  EXPECT_EQ(row["name"], "warp bilinear 512x512x3");
  EXPECT_EQ(row["unit"], "Mpix/s");
  EXPECT_EQ(row["peer"], "cv::remap");
  EXPECT_GT(row["value"].get<double>(), 0);
  EXPECT_GT(row["peer_value"].get<double>(), 0);
  EXPECT_NEAR(row["ratio_vs_peer"].get<double>(),
              row["value"].get<double>() / row["peer_value"].get<double>(), 1e-9);
  EXPECT_FALSE(row.contains("fraction_of_device_peak"));  // memory-bound: no peak fraction
  EXPECT_FALSE(written.contains("device_fma_peak_gflops"));
}

// The pipeline with its restore paths on one weak probe: restore-all against
// the plain protocol, the gate (which skips it) against restore-all.
TEST(CliBenchPipeline, RestoreAllAndGatedPaths) {
  const auto r = run_cli("bench pipeline --probes 1 --frames 10 --runs 1 --no-tfjs --json");
  ASSERT_EQ(r.code, 0) << r.output;
  const json j = parse_json(r.output.substr(r.output.find("\n{")));
  ASSERT_EQ(j["results"].size(), 4u) << j.dump();
  EXPECT_EQ(j["results"][2]["peer"], "pipeline protocol, no restoration");
  EXPECT_EQ(j["results"][3]["peer"], "restore-all");
  for (const json& row : j["results"]) EXPECT_GT(row["value"].get<double>(), 0) << row.dump();
  EXPECT_EQ(j["gate"]["probes"], 1);
  EXPECT_EQ(j["d_over_r0"][0], 1.5);
  EXPECT_GT(j["stages_per_probe"]["restore_all"]["total_s"].get<double>(), 0);
}

TEST(CliBenchKernels, UnknownBenchmarkIsAUsageError) {
  const auto r = run_cli("bench kernels --only warp,no-such-kernel");
  EXPECT_EQ(r.code, 2) << r.output;
  EXPECT_NE(r.output.find("no-such-kernel"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("fft-256"), std::string::npos) << r.output;  // lists the known ones
}

TEST(CliBench, HelpListsTheBenchmarks) {
  const auto r = run_cli("bench --help");
  EXPECT_EQ(r.code, 0) << r.output;
  for (const char* name : {"sim_bench", "kernels_bench", "runtime_bench", "nets_bench"}) {
    EXPECT_NE(r.output.find(name), std::string::npos) << name << "\n" << r.output;
  }
}

TEST(CliBench, UnknownOrMissingBenchmarkIsAUsageError) {
  auto r = run_cli("bench gpu");
  EXPECT_EQ(r.code, 2) << r.output;
  EXPECT_NE(r.output.find("gpu"), std::string::npos) << r.output;
  r = run_cli("bench");
  EXPECT_EQ(r.code, 2) << r.output;
}

// The launcher runs the program VKJR2_BENCH_DIR names first, as
// "vkjr2 bench NAME", with the options after NAME untouched, and its exit
// code is the command's.
TEST(CliBench, RunsTheProgramWithItsOptions) {
  TempDir tmp("bench_launcher");
  const fs::path program = tmp.path / "sim_bench";
  {
    std::ofstream f(program);
    f << "#!/bin/sh\necho \"argv0=$0 args=$*\"\nexit 7\n";
  }
  fs::permissions(program, fs::perms::owner_all);
  const auto r =
      run_cli("bench sim --sizes 64 --frames 1 --json", "VKJR2_BENCH_DIR=" + tmp.path.string());
  EXPECT_EQ(r.code, 7) << r.output;
  EXPECT_NE(r.output.find("args=--sizes 64 --frames 1 --json"), std::string::npos) << r.output;
}

}  // namespace
