// kernels_bench: the compute core on this device, each kernel against the
// peer a user would pick instead (OpenCV, FFTW, plain C++), measured in the
// same run (bench/kernels_cases.cpp; `vkjr2 bench kernels` runs the same).
// Prints a table and writes JSON.
#include <cstdio>
#include <string>
#include <vector>

#include "kernels_cases.hpp"

namespace vkjr2 {
namespace {

int run(int argc, char** argv) {
  std::string json_path = "kernels_bench.json";
  bool full = false;
  std::vector<std::string> only;
  for (int i = 1; i < argc; ++i) {
    const std::string arg = argv[i];
    if (arg == "--json" && i + 1 < argc) {
      json_path = argv[++i];
    } else if (arg == "--only" && i + 1 < argc) {
      only.emplace_back(argv[++i]);
    } else if (arg == "--full") {
      full = true;
    } else if (arg == "--help" || arg == "-h") {
      std::printf(
          "usage: kernels_bench [--json FILE] [--full] [--only NAME]...\n"
          "Times vkjr2's kernels on the Vulkan device (VKJR2_DEVICE picks it) against OpenCV,\n"
          "FFTW and plain C++ on this machine; prints a table and writes JSON (default\n"
          "kernels_bench.json). --full adds the direct PSF-basis case (K=100, 33x33, 256^2),\n"
          "which takes minutes. --only runs the named cases:\n");
      for (const bench::KernelCase& c : bench::kernel_cases()) {
        std::printf("  %-15s %s\n", c.id.c_str(), c.description.c_str());
      }
      return 0;
    } else {
      std::fprintf(stderr, "kernels_bench: unknown argument '%s' (try --help)\n", arg.c_str());
      return 2;
    }
  }
  DeviceOptions options;
  options.validation = false;
  const Device dev(options);
  const bench::KernelsRun results = bench::run_kernel_cases(dev, only, full, "kernels_bench");
  bench::print_kernels_table(dev, results);
  bench::write_json(json_path, bench::kernels_json(dev, results));
  std::printf("wrote %s\n", json_path.c_str());
  return 0;
}

}  // namespace
}  // namespace vkjr2

int main(int argc, char** argv) {
  try {
    return vkjr2::run(argc, argv);
  } catch (const std::exception& e) {
    std::fprintf(stderr, "kernels_bench: error: %s\n", e.what());
    return 1;
  }
}
