// Nothing left behind (cli/cleanup.cpp): interrupted commands remove their
// temporary outputs and the folders they made and exit 130 / 143; a failed
// command removes the folders it made; a folder run reports a bad file and
// goes on.
#include "cli/cleanup.hpp"

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>
#include <sys/wait.h>
#include <unistd.h>

#include <array>
#include <chrono>
#include <csignal>
#include <filesystem>
#include <fstream>
#include <string>
#include <thread>
#include <vector>

#include "cli/media.hpp"
#include "support/cli_checks.hpp"
#include "support/cli_files.hpp"
#include "support/run_cli.hpp"

namespace {

namespace fs = std::filesystem;
using nlohmann::json;
using vkjr2::test::error_lines;
using vkjr2::test::parse_json;
using vkjr2::test::run_cli;
using vkjr2::test::TempDir;
using vkjr2::test::temporaries;
using vkjr2::test::write_noise_image;
using vkjr2::test::write_truncated;

struct Finished {
  int exit_code = -1;
  std::string stderr_text;
};

// Starts vkjr2 with `args`, waits until a temporary output appears under
// `watch`, sends `sig`, and returns how the command ended.
Finished interrupt(const std::vector<std::string>& args, const fs::path& watch, int sig,
                   const fs::path& log) {
  const pid_t pid = ::fork();
  if (pid == 0) {
    std::vector<char*> argv;
    std::string prog = VKJR2_CLI_PATH;
    argv.push_back(prog.data());
    std::vector<std::string> copy = args;
    for (std::string& a : copy) argv.push_back(a.data());
    argv.push_back(nullptr);
    if (std::freopen(log.c_str(), "w", stderr) == nullptr) ::_exit(99);
    if (std::freopen("/dev/null", "w", stdout) == nullptr) ::_exit(99);
    ::execv(VKJR2_CLI_PATH, argv.data());
    ::_exit(98);
  }
  Finished f;
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(90);
  while (std::chrono::steady_clock::now() < deadline) {
    if (!temporaries(watch).empty()) break;
    int status = 0;
    if (::waitpid(pid, &status, WNOHANG) == pid) {  // ended before writing anything
      f.exit_code = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
      return f;
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
  }
  EXPECT_FALSE(temporaries(watch).empty()) << "no temporary output appeared";
  std::this_thread::sleep_for(std::chrono::milliseconds(200));  // mid-write
  ::kill(pid, sig);
  int status = 0;
  ::waitpid(pid, &status, 0);
  f.exit_code = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
  std::ifstream in(log);
  f.stderr_text.assign(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
  return f;
}

// Issue case 7: SIGTERM and SIGINT during a long command.
TEST(CliCleanup, SignalsRemoveTemporaryOutputs) {
  TempDir tmp("cleanup_signal");
  const fs::path in = write_noise_image(tmp.path / "in.png", 96, 128);
  const fs::path out_dir = tmp.path / "out";
  fs::create_directories(out_dir);
  const fs::path out = out_dir / "long.avi";
  const Finished term =
      interrupt({"simulate", in.string(), out.string(), "--frames", "100000", "--quiet"}, out_dir,
                SIGTERM, tmp.path / "term.log");
  EXPECT_EQ(term.exit_code, 143) << term.stderr_text;
  EXPECT_EQ(error_lines(term.stderr_text), 1) << term.stderr_text;
  EXPECT_NE(term.stderr_text.find("SIGTERM"), std::string::npos) << term.stderr_text;
  EXPECT_TRUE(temporaries(out_dir).empty());
  EXPECT_FALSE(fs::exists(out));

  // A folder run into a folder the command creates: both go on SIGINT.
  const fs::path in_dir = tmp.path / "in";
  fs::create_directories(in_dir);
  fs::copy_file(in, in_dir / "a.png");
  const fs::path made = tmp.path / "made";
  const Finished intr =
      interrupt({"simulate", in_dir.string(), made.string(), "--frames", "100000", "--quiet"},
                tmp.path, SIGINT, tmp.path / "int.log");
  EXPECT_EQ(intr.exit_code, 130) << intr.stderr_text;
  EXPECT_NE(intr.stderr_text.find("SIGINT"), std::string::npos) << intr.stderr_text;
  EXPECT_TRUE(temporaries(tmp.path).empty());
  EXPECT_FALSE(fs::exists(made)) << "the folder the command made is left";
}

// The interruption message reaches the command's stderr even when the signal
// lands while a decoder call has descriptor 2 pointed at /dev/null
// (QuietDecoders around every image and video read or write): it had gone to
// /dev/null about once in fifty runs of the test above.
TEST(CliCleanup, InterruptionMessageGetsPastQuietDecoders) {
  std::array<int, 2> fds{};
  ASSERT_EQ(::pipe(fds.data()), 0);
  const pid_t pid = ::fork();
  if (pid == 0) {  // one thread here: this test runs alone in its process
    ::dup2(fds[1], STDERR_FILENO);
    ::close(fds[0]);
    ::close(fds[1]);
    vkjr2::cli::install_signal_cleanup();
    const vkjr2::cli::QuietDecoders quiet;
    ::kill(::getpid(), SIGTERM);
    for (;;) ::pause();  // the signal thread ends the process
  }
  ::close(fds[1]);
  std::string text;
  std::array<char, 256> buf{};
  ssize_t n = 0;
  while ((n = ::read(fds[0], buf.data(), buf.size())) > 0) text.append(buf.data(), std::size_t(n));
  ::close(fds[0]);
  int status = 0;
  ::waitpid(pid, &status, 0);
  ASSERT_TRUE(WIFEXITED(status));
  EXPECT_EQ(WEXITSTATUS(status), 143);
  EXPECT_NE(text.find("interrupted by SIGTERM"), std::string::npos) << text;
}

// Issue case 9: a demo that fails leaves no --out folder behind.
TEST(CliCleanup, FailedDemoLeavesNoFolder) {
  TempDir tmp("cleanup_demo");
  std::ofstream(tmp.path / "bad.avi") << "not a video at all";
  const fs::path out = tmp.path / "demo_out";
  const auto r = run_cli("demo-turbulence --out " + out.string() + " --video " +
                         (tmp.path / "bad.avi").string() + " --photos 1 --quiet");
  EXPECT_EQ(r.code, 1) << r.output;
  EXPECT_EQ(error_lines(r.output), 1) << r.output;
  EXPECT_FALSE(fs::exists(out)) << r.output;
}

// Issue case 10: a folder or batch run reports a bad file, goes on with the
// rest, prints a summary and exits 1; --fail-fast stops at the first.
TEST(CliCleanup, BatchesGoOnPastABadFile) {
  TempDir tmp("cleanup_batch");
  const fs::path in = tmp.path / "in";
  fs::create_directories(in);
  write_noise_image(in / "good.png", 32, 40);
  write_noise_image(tmp.path / "whole.png", 32, 40);
  write_truncated(tmp.path / "whole.png", in / "a_bad.png", 0.5);  // sorted first
  const fs::path out = tmp.path / "out";
  auto r = run_cli("simulate " + in.string() + " " + out.string() + " --quiet");
  EXPECT_EQ(r.code, 1) << r.output;
  EXPECT_EQ(error_lines(r.output), 1) << r.output;
  EXPECT_NE(r.output.find("skipped " + (in / "a_bad.png").string()), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("1 of 2 inputs failed"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("1 of 2 files written"), std::string::npos) << r.output;
  EXPECT_TRUE(fs::exists(out / "good.png"));
  EXPECT_FALSE(fs::exists(out / "a_bad.png"));
  EXPECT_TRUE(temporaries(tmp.path).empty());
  // --json lists the failure.
  r = run_cli("simulate " + in.string() + " " + out.string() + " --quiet --force --json");
  EXPECT_EQ(r.code, 1) << r.output;
  const json j = parse_json(r.output);
  ASSERT_TRUE(j.is_object()) << r.output;
  ASSERT_EQ(j["failed"].size(), 1u) << r.output;
  EXPECT_EQ(j["files"].size(), 1u) << r.output;
  // --fail-fast: stop at the bad file, nothing after it is written.
  const fs::path out2 = tmp.path / "out2";
  r = run_cli("simulate " + in.string() + " " + out2.string() + " --quiet --fail-fast");
  EXPECT_EQ(r.code, 1) << r.output;
  EXPECT_EQ(error_lines(r.output), 1) << r.output;
  EXPECT_FALSE(fs::exists(out2 / "good.png"));
  EXPECT_FALSE(fs::exists(out2)) << "the folder it made for nothing is left";

  // embed: the good image is described, the bad one reported; exit 1.
  r = run_cli("embed " + in.string() + " --aligned --json");
  EXPECT_EQ(r.code, 1) << r.output;
  EXPECT_EQ(error_lines(r.output), 1) << r.output;
  const json e = parse_json(r.output);
  ASSERT_TRUE(e.is_array()) << r.output;
  ASSERT_EQ(e.size(), 1u) << r.output;
  EXPECT_EQ(e[0]["input"], (in / "good.png").string());
  r = run_cli("embed " + in.string() + " --aligned --fail-fast");
  EXPECT_EQ(r.code, 1) << r.output;
  EXPECT_EQ(r.output.find("good.png"), std::string::npos) << r.output;

  // identify: a bad gallery image is skipped and reported.
  const fs::path gallery = tmp.path / "gallery";
  fs::create_directories(gallery / "alice");
  fs::create_directories(gallery / "bob");
  fs::copy_file(in / "good.png", gallery / "alice" / "a.png");
  fs::copy_file(in / "a_bad.png", gallery / "bob" / "b.png");
  r = run_cli("identify " + (in / "good.png").string() + " --gallery " + gallery.string() +
              " --aligned");
  EXPECT_EQ(r.code, 1) << r.output;
  EXPECT_EQ(error_lines(r.output), 1) << r.output;
  EXPECT_NE(r.output.find("1. alice"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("1 of 2 gallery images failed"), std::string::npos) << r.output;
}

}  // namespace
