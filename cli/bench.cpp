// vkjr2 bench NAME [OPTIONS]: runs one of the benchmark programs of bench/
// (each a peer measured in the same run; bench/RESULTS.md). The command
// runner links none of them: it finds the program beside itself (the build
// tree's bench/ folder, or the installed libexec/vkjr2/) and replaces itself
// with it, passing the options on.
#include <vkjr2/runtime/error.hpp>

#include <CLI/CLI.hpp>
#include <unistd.h>

#include <array>
#include <cerrno>
#include <csignal>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <iostream>
#include <memory>
#include <string>
#include <string_view>
#include <vector>

#include "checks.hpp"
#include "commands.hpp"
#include "run.hpp"

namespace vkjr2::cli {
namespace {

namespace fs = std::filesystem;

struct Benchmark {
  const char* name;
  const char* program;
  const char* what;
};

constexpr std::array<Benchmark, 8> kBenchmarks{{
    {"sim", "sim_bench",
     "fast simulator frames/s and speedup over the wave-optics reference (device and FFTW CPU)"},
    {"kernels", "kernels_bench", "each kernel against OpenCV, FFTW or plain C++"},
    {"runtime", "runtime_bench", "dispatch cost, copy bandwidth and FMA throughput of the device"},
    {"nets", "nets_bench", "the face networks against face-api on TF.js WASM and OpenCV DNN"},
    {"pipeline", "pipeline_bench",
     "probe videos/s through the JR² recognition pipeline against face-api on TF.js WASM"},
    {"restore", "restore_bench",
     "the restorer's inference frames/s and training steps/s against PyTorch on the CPU"},
    {"cotrain", "cotrain_bench",
     "a JR² co-training step, stage by stage, and its device memory against PyTorch on the CPU"},
    {"estimate", "estimate_bench",
     "the turbulence estimate's tilt registration against OpenCV DIS optical flow"},
}};

const Benchmark* find_benchmark(std::string_view name) {
  for (const Benchmark& b : kBenchmarks) {
    if (name == b.name) return &b;
  }
  return nullptr;
}

// Where the program may be: $VKJR2_BENCH_DIR, else beside this executable in
// the build tree (cli/vkjr2 → bench/) or installed (bin/vkjr2 → libexec/vkjr2/).
std::vector<fs::path> candidates(const char* program) {
  std::vector<fs::path> out;
  if (const char* dir = std::getenv("VKJR2_BENCH_DIR")) out.push_back(fs::path(dir) / program);
  std::error_code ec;
  const fs::path self = fs::read_symlink("/proc/self/exe", ec);
  if (!ec) {
    const fs::path dir = self.parent_path();
    out.push_back(dir.parent_path() / "bench" / program);
    out.push_back(dir.parent_path() / "libexec" / "vkjr2" / program);
  }
  return out;
}

[[noreturn]] void run_benchmark(const Benchmark& b, const std::vector<std::string>& options) {
  const std::vector<fs::path> places = candidates(b.program);
  std::string looked;
  for (const fs::path& p : places) {
    if (::access(p.c_str(), X_OK) != 0) {
      looked += (looked.empty() ? "" : ", ") + p.string();
      continue;
    }
    std::vector<std::string> args{"vkjr2 bench " + std::string(b.name)};
    args.insert(args.end(), options.begin(), options.end());
    std::vector<char*> argv;
    for (std::string& a : args) argv.push_back(a.data());
    argv.push_back(nullptr);
    std::cout.flush();
    std::fflush(stdout);
    // The program handles its own signals: nothing stays blocked across exec.
    sigset_t none;
    sigemptyset(&none);
    pthread_sigmask(SIG_SETMASK, &none, nullptr);
    ::execv(p.c_str(), argv.data());
    throw Error("vkjr2 bench " + std::string(b.name),
                "cannot run " + p.string() + ": " + std::strerror(errno),
                "check that the file is an executable for this machine");
  }
  throw Error(
      "vkjr2 bench " + std::string(b.name),
      "the benchmark program " + std::string(b.program) +
          " is not built or installed (looked for " + looked + ")",
      "build with -DVKJR2_BUILD_BENCH=ON (runtime and nets need it; the others are built with "
      "the command runner), or point VKJR2_BENCH_DIR at the folder that holds it");
}

}  // namespace

bool is_benchmark(std::string_view name) { return find_benchmark(name) != nullptr; }

int run_benchmark(std::string_view name, int argc, char** argv) {
  try {
    run_benchmark(*find_benchmark(name), std::vector<std::string>(argv, argv + argc));
  } catch (const Error& e) {
    print_error(describe_error(e));
  }
  return 1;
}

void add_bench(CLI::App& app) {
  CLI::App* cmd = app.add_subcommand("bench", "Benchmarks with a peer measured in the same run");
  // `vkjr2 bench NAME ...` is handed to the program before parsing (main.cpp);
  // this parser gives the help, the list and the errors, and takes what
  // reaches it after global options (`vkjr2 --verbose bench sim ...`).
  cmd->allow_extras();
  auto name = std::make_shared<std::string>();
  std::vector<std::string> names;
  std::string list;
  for (const Benchmark& b : kBenchmarks) {
    names.emplace_back(b.name);
    list += "\n  " + std::string(b.name) + std::string(10 - std::strlen(b.name), ' ') + b.what +
            " (" + b.program + ")";
  }
  cmd->add_option("benchmark", *name, "Which benchmark to run (below)")
      ->required()
      ->check(CLI::IsMember(names));
  cmd->footer("Benchmarks:" + list +
              "\nOptions after NAME are the benchmark's: `vkjr2 bench NAME --help` lists them.\n"
              "Examples:\n  vkjr2 bench sim --sizes 256 --json-file bench_sim.json\n"
              "  vkjr2 bench kernels --only warp,add\n"
              "The latest figures and the machines they came from: bench/RESULTS.md.");
  // The name is checked above (IsMember).
  cmd->callback([cmd, name] { run_benchmark(*find_benchmark(*name), cmd->remaining()); });
}

}  // namespace vkjr2::cli
