// kernels_bench (run by `vkjr2 bench kernels`): the compute core on this
// device, each kernel against the peer a user would pick instead (OpenCV,
// FFTW, plain C++), measured in the same run (bench/kernels_cases.cpp).
// Prints a table; writes JSON with --json-file.
#include <vkjr2/runtime/device.hpp>

#include <CLI/CLI.hpp>
#include <nlohmann/json.hpp>

#include <cstdio>
#include <string>
#include <vector>

#include "cli/checks.hpp"
#include "cli/log.hpp"
#include "cli/run.hpp"
#include "kernels_cases.hpp"

namespace {

struct Args {
  std::string device, json_path;
  std::vector<std::string> only;
  bool full = false;
  bool json_out = false;
};

void run(const Args& a) {
  if (!a.json_path.empty()) vkjr2::cli::check_output_file(a.json_path, true, "--json-file");
  const vkjr2::Device device = vkjr2::cli::open_device(a.device);
  const vkjr2::bench::KernelsRun run =
      vkjr2::bench::run_kernel_cases(device, a.only, a.full, "bench kernels");
  vkjr2::bench::print_kernels_table(device, run);
  const nlohmann::json out = vkjr2::bench::kernels_json(device, run);
  vkjr2::bench::emit_json(out, a.json_path, a.json_out);
}

}  // namespace

namespace {

int run(int argc, char** argv) {
  CLI::App app{"Kernels vs OpenCV, FFTW and plain C++ on this machine (bench/kernels_bench)",
               "vkjr2 bench kernels"};
  vkjr2::cli::add_logging_options(app);
  Args a;
  std::string names;
  for (const vkjr2::bench::KernelCase& c : vkjr2::bench::kernel_cases()) {
    names +=
        "\n  " + c.id + std::string(c.id.size() < 15 ? 15 - c.id.size() : 1, ' ') + c.description;
  }
  app.footer(
      "Example:\n  vkjr2 bench kernels --only warp,add --json-file kernels.json\n"
      "Benchmarks (--only; psf-direct-100 runs only with --full or when named):" +
      names);
  app.add_option("--only", a.only, "Run only these benchmarks (comma-separated)")
      ->delimiter(',')
      ->check(CLI::IsMember(vkjr2::bench::kernel_case_ids()));
  app.add_flag("--full", a.full, "Also run the direct PSF-basis K=100 case (minutes)");
  app.add_option("--device", a.device, "Vulkan device index or name substring (else VKJR2_DEVICE)");
  app.add_option("--json-file", a.json_path, "Also write the results as JSON here");
  app.add_flag("--json", a.json_out, "Print the JSON after the table");
  app.callback([&a] { run(a); });
  return vkjr2::cli::run_program(app, argc, argv);
}

}  // namespace

int main(int argc, char** argv) { return vkjr2::cli::program_main(argc, argv, run); }
