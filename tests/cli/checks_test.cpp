// The command line's checks (cli/checks.cpp, main.cpp): exit code 2 and one
// "vkjr2: error:" line for every mistake on the command line, found before
// any work; numbers without NaN, infinity or wrapped seeds; messages in the
// user's words.
#include <gtest/gtest.h>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>

#include <filesystem>
#include <string>
#include <utility>
#include <vector>

#include "support/cli_checks.hpp"
#include "support/cli_files.hpp"
#include "support/run_cli.hpp"

namespace {

namespace fs = std::filesystem;
using vkjr2::test::error_lines;
using vkjr2::test::lines_of;
using vkjr2::test::run_cli;
using vkjr2::test::TempDir;
using vkjr2::test::temporaries;

fs::path write_png(const fs::path& dir, int h, int w, const std::string& name = "in.png") {
  return vkjr2::test::write_noise_image(dir / name, h, w);
}

// A usage error: exit code 2, one line, naming `needle`; no device was opened
// (--log-level info would have said so) and nothing was written.
void expect_usage_error(const std::string& args, const std::string& needle) {
  const auto r = run_cli(args + " --log-level info");
  EXPECT_EQ(r.code, 2) << args << "\n" << r.output;
  EXPECT_EQ(lines_of(r.output).size(), 1u) << args << "\n" << r.output;
  EXPECT_EQ(error_lines(r.output), 1) << args << "\n" << r.output;
  EXPECT_NE(r.output.find(needle), std::string::npos) << args << "\n" << r.output;
  EXPECT_EQ(r.output.find("info: device"), std::string::npos) << args << "\n" << r.output;
}

// Issue case 3: NaN and infinity are refused wherever a float is taken.
TEST(CliChecks, FloatOptionsRefuseNanAndInfinity) {
  TempDir tmp("checks_nan");
  const fs::path in = write_png(tmp.path, 16, 16);
  const std::string sim = "simulate " + in.string() + " " + (tmp.path / "o.png").string();
  // (command and its positionals, option)
  const std::vector<std::pair<std::string, std::string>> floats = {
      {"verify " + in.string() + " " + in.string(), "--threshold"},
      {sim, "--photons"},
      {sim, "--read-noise"},
      {sim, "--tilt-rho"},
      {sim, "--r0"},
      {sim, "--cn2"},
      {sim, "--range"},
      {"detect " + in.string(), "--min-score"},
      {"wave " + in.string() + " o.png", "--source-step"}};
  const std::vector<std::string> values =
      vkjr2::test::kSanitized ? std::vector<std::string>{"nan"}
                              : std::vector<std::string>{"nan", "inf", "-inf", "NaN"};
  for (const std::string& value : values) {
    for (const auto& [command, option] : floats) {
      std::string args = command;
      args.append(" ").append(option).append(" ").append(value);
      expect_usage_error(args, option);
    }
  }
  expect_usage_error(sim + " --photons -1", "--photons");
  expect_usage_error(sim + " --read-noise 2", "--read-noise");
}

// Issue case 4: a seed is a non-negative integer that fits 64 bits.
TEST(CliChecks, SeedsAreWholeNumbersThatFit) {
  TempDir tmp("checks_seed");
  const fs::path in = write_png(tmp.path, 16, 16);
  const std::string sim = "simulate " + in.string() + " " + (tmp.path / "o.png").string();
  for (const char* v : {"-1", "1e23", "18446744073709551616", "1.5", "abc", "0x10", "nan"})
    expect_usage_error(sim + " --seed " + std::string(v), "--seed");
  expect_usage_error("wave " + in.string() + " o.png --seed -1", "--seed");
  expect_usage_error("sim-train o.safetensors --basis-seed -3", "--basis-seed");
  expect_usage_error("sim-validate --seed 1e30", "--seed");
  expect_usage_error("demo --seed -2", "--seed");
  // The largest seed is taken as it is, and seeds that differ give different turbulence.
  const auto r = run_cli(sim + " --seed 18446744073709551615 --json --quiet");
  ASSERT_EQ(r.code, 0) << r.output;
  EXPECT_NE(r.output.find("\"seed\": 18446744073709551615"), std::string::npos) << r.output;
}

// Issue case 11: every mistake on the command line is exit code 2, the same
// for every command; a missing input too.
TEST(CliChecks, UsageErrorsExitTwo) {
  TempDir tmp("checks_usage");
  const fs::path in = write_png(tmp.path, 16, 16);
  const fs::path out = tmp.path / "o.png";
  const std::string sim = "simulate " + in.string() + " " + out.string();
  expect_usage_error(sim + " --r0 0.05 --cn2 1e-14", "--cn2");
  expect_usage_error(sim + " --wavelengths 500,510,520,530,540", "--wavelengths");
  expect_usage_error(sim + " --wavelengths 610,525", "--wavelengths");
  expect_usage_error("detect " + in.string() + " --input-size 33", "--input-size");
  expect_usage_error("wave " + in.string() + " " + out.string() + " --grid 17", "--grid");
  expect_usage_error("wave " + in.string() + " " + out.string() + " --psf-size 4", "--psf-size");
  expect_usage_error("sim-train m.safetensors --size 8", "--size");
  expect_usage_error(sim + " --device 99", "--device");
  expect_usage_error(sim + " --device no-such-gpu", "--device");
  expect_usage_error(sim + " --frames 0", "--frames");  // issue case 6
  expect_usage_error(sim + " --frames 3", "video output");
  expect_usage_error(sim + " --r0 0.0001", "D/r0");  // physically absurd: the limit is named
  const std::string missing = (tmp.path / "missing.png").string();
  expect_usage_error("simulate " + missing + " " + out.string(), "does not exist");
  expect_usage_error("detect " + missing, "does not exist");
  expect_usage_error("embed " + missing, "does not exist");
  expect_usage_error("verify " + in.string() + " " + missing, "does not exist");
  expect_usage_error("identify " + missing + " --gallery " + tmp.path.string(), "does not exist");
  expect_usage_error("identify " + in.string() + " --gallery " + missing, "does not exist");
  expect_usage_error("wave " + missing + " " + out.string(), "does not exist");
  expect_usage_error(sim + " --config " + missing, "does not exist");
  EXPECT_FALSE(fs::exists(out));
  // --help documents the codes.
  const auto help = run_cli("--help");
  EXPECT_EQ(help.code, 0);
  EXPECT_NE(help.output.find("2 a usage error"), std::string::npos) << help.output;
  EXPECT_NE(help.output.find("130/143"), std::string::npos) << help.output;
}

// Issue cases 8 and 9: output paths are checked before any work.
TEST(CliChecks, OutputPathsAreCheckedFirst) {
  TempDir tmp("checks_out");
  const fs::path in = write_png(tmp.path, 16, 16);
  const fs::path existing = write_png(tmp.path, 8, 8, "existing.png");
  const fs::path folder = tmp.path / "folder";
  fs::create_directories(folder);
  const std::string sim = "simulate " + in.string() + " ";
  expect_usage_error(sim + existing.string(), "--force");
  expect_usage_error(sim + folder.string() + " --force", "is a folder");
  expect_usage_error(sim + (tmp.path / "no" / "such" / "o.png").string(), "does not exist");
  expect_usage_error(sim + (tmp.path / "o.gif").string(), "OUT");
  expect_usage_error("wave " + in.string() + " " + folder.string() + " --force", "is a folder");
  expect_usage_error("detect " + in.string() + " --draw " + folder.string() + " --force",
                     "is a folder");
  expect_usage_error("detect " + in.string() + " --draw " + existing.string(), "--force");
  expect_usage_error("sim-train " + folder.string() + " --force", "is a folder");
  expect_usage_error("sim-train " + (tmp.path / "none" / "m.safetensors").string(),
                     "does not exist");
  expect_usage_error("bench sim --json-file " + (tmp.path / "none" / "b.json").string(),
                     "does not exist");
  expect_usage_error("demo --out " + in.string(), "not a folder");
  expect_usage_error("demo --out " + (tmp.path / "a" / "b").string(), "does not exist");
  EXPECT_TRUE(temporaries(tmp.path).empty());
  EXPECT_FALSE(fs::exists(tmp.path / "a"));
}

// Issue case 12: one line in the user's words: no doubled option names, no
// library function names, readable numbers.
TEST(CliChecks, MessagesAreOneReadableLine) {
  TempDir tmp("checks_words");
  const fs::path in = write_png(tmp.path, 16, 16);
  const std::string sim = "simulate " + in.string() + " " + (tmp.path / "o.png").string();
  for (const std::string& args : std::vector<std::string>{
           sim + " --wavelengths red", sim + " --wavelengths 50", sim + " --r0 0.0001",
           sim + " --range 1e7", sim + " --photons 1e13",
           "verify " + in.string() + " " + in.string() + " --threshold 0",
           sim + " --preset hurricane", std::string("frobnicate"), sim + " --no-such-option"}) {
    const auto r = run_cli(args);
    EXPECT_EQ(r.code, 2) << args << "\n" << r.output;
    ASSERT_EQ(lines_of(r.output).size(), 1u) << args << "\n" << r.output;
    EXPECT_TRUE(r.output.starts_with("vkjr2: error: ")) << r.output;
    EXPECT_EQ(r.output.find("--wavelengths: --wavelengths"), std::string::npos) << r.output;
    EXPECT_EQ(r.output.find("::"), std::string::npos) << args << "\n" << r.output;
    EXPECT_EQ(r.output.find("path.r0_m"), std::string::npos) << r.output;
    EXPECT_EQ(r.output.find("179769"), std::string::npos) << r.output;  // DBL_MAX digits
    EXPECT_LT(r.output.size(), 400u) << r.output;
  }
}

}  // namespace
