// `vkjr2 gate train` and `vkjr2 eval --method gated:…` as a user runs them:
// a gate labelled on a tiny benchmark's val probes with the shipped
// restorer, its threshold chosen on the test probes, its label cache reused,
// the gated evaluation, and bad input as clear errors.
#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

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

TEST(CliGate, TrainsOnLabelsFromThePipelineAndGatesTheEvaluation) {
  TempDir tmp("cli_gate");
  const fs::path bench = tmp.path / "bench", gate = tmp.path / "gate.safetensors";
  const fs::path labels = tmp.path / "labels.json";
  auto r = run_cli("dataset make --out " + bench.string() +
                   " --max-identities 4 --strengths weak,moderate --frames 10 --clip-size 96 "
                   "--face-px 64 --quiet");
  ASSERT_EQ(r.code, 0) << r.output;
  const std::string manifest = (bench / "manifest.json").string();
  const std::string train = "gate train " + gate.string() + " --train " + manifest +
                            " --train-splits val --validation " + manifest +
                            " --validation-split test --samples " + labels.string() +
                            " --steps 200 --quiet --json";
  r = run_cli(train);
  ASSERT_EQ(r.code, 0) << r.output;
  const json first = parse_json(r.output);
  EXPECT_EQ(first["train"]["all"]["probes"], 8);  // 4 identities × 2 strengths
  EXPECT_EQ(first["validation"]["all"]["probes"], 8);
  EXPECT_EQ(first["train"]["all"]["mated"], 4);
  const json& v = first["validation"]["all"];
  // The chosen threshold is at least as good as never or always restoring.
  EXPECT_GE(v["mrr"]["gated"].get<double>() + 1e-12,
            std::max(v["mrr"]["degraded"].get<double>(), v["mrr"]["restored"].get<double>()));
  ASSERT_TRUE(fs::exists(gate));
  std::ifstream cache_file(labels);
  const json cache = json::parse(cache_file);
  ASSERT_EQ(cache["train"]["samples"].size(), 8u);
  for (const json& s : cache["train"]["samples"]) {
    EXPECT_GT(s["d_over_r0"].get<double>(), 0.0) << s.dump();
    if (s["mated"].get<bool>()) {
      EXPECT_GE(s["rank_raw"].get<int>(), 1) << s.dump();
    }
  }

  // Again from the cache: the same gate, byte for byte.
  const fs::path again = tmp.path / "again.safetensors";
  std::string train2 = train;
  train2.replace(train2.find(gate.string()), gate.string().size(), again.string());
  r = run_cli(train2);
  ASSERT_EQ(r.code, 0) << r.output;
  EXPECT_EQ(parse_json(r.output)["validation"], first["validation"]);
  EXPECT_EQ(vkjr2::test::read_bytes(gate), vkjr2::test::read_bytes(again));

  // The gate in the evaluation: every probe it sees is restored or skipped.
  const fs::path out = tmp.path / "eval";
  r = run_cli("eval " + manifest + " --out " + out.string() + " --method degraded,gated:restored," +
              gate.string() +
              " --align similarity --input-sizes 160 --resamples 20 --quiet --json");
  ASSERT_EQ(r.code, 0) << r.output;
  const json e = parse_json(r.output);
  int gated_rows = 0;
  for (const json& row : e["rows"]) {
    EXPECT_GT(row["seconds_per_probe"]["value"].get<double>(), 0.0) << row.dump();
    if (row["method"].get<std::string>().rfind("gated:", 0) != 0) {
      EXPECT_FALSE(row.contains("gate"));
      continue;
    }
    ++gated_rows;
    EXPECT_EQ(row["gate"]["probes"], row["probes"]);
    EXPECT_LE(row["gate"]["restored"].get<int>(), row["probes"].get<int>());
  }
  EXPECT_EQ(gated_rows, 2);  // weak and moderate

  // Bad input: a gated method without its gate, a file that is not a gate,
  // a validation split the gate trains on, a missing benchmark.
  r = run_cli("eval " + manifest + " --out " + (tmp.path / "e2").string() +
              " --method gated:restored");
  EXPECT_EQ(r.code, 2) << r.output;
  EXPECT_NE(r.output.find("does not name a restorer and a gate"), std::string::npos) << r.output;
  r = run_cli("eval " + manifest + " --out " + (tmp.path / "e3").string() +
              " --method gated:restored," + labels.string() + " --quiet");
  EXPECT_EQ(r.code, 1) << r.output;
  EXPECT_NE(r.output.find(labels.string()), std::string::npos) << r.output;
  r = run_cli("gate train " + (tmp.path / "g2.safetensors").string() + " --train " + manifest +
              " --train-splits val,test --validation " + manifest + " --validation-split test");
  EXPECT_EQ(r.code, 2) << r.output;
  EXPECT_NE(r.output.find("both trained and validated on"), std::string::npos) << r.output;
  r = run_cli("gate train " + (tmp.path / "g3.safetensors").string() + " --train " +
              (tmp.path / "missing.json").string());
  EXPECT_EQ(r.code, 2) << r.output;
  EXPECT_NE(r.output.find("missing.json"), std::string::npos) << r.output;
  // Refused over an existing gate without --force, before any work.
  r = run_cli(train);
  EXPECT_EQ(r.code, 2) << r.output;
}

}  // namespace
