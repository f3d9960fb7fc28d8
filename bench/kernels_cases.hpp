// The kernels benchmarks (each kernel against the peer a user would pick
// instead: OpenCV, FFTW, plain C++), shared by bench/kernels_bench and
// `vkjr2 bench kernels` (cli/bench.cpp) so both run the same code.
#pragma once

#include <vkjr2/runtime/device.hpp>

#include <functional>
#include <string>
#include <vector>

#include "harness.hpp"

namespace vkjr2::bench {

struct KernelCase {
  std::string id;           // what --only takes, e.g. "warp"
  std::string description;  // one line for --help
  bool full_only = false;   // minutes long: run only with --full or when named in --only
  bool needs_peak = false;  // reports a fraction of the device FMA peak
  std::function<Result(const Device&, double peak_gflops)> run;
};

// Every case, in table order.
const std::vector<KernelCase>& kernel_cases();
std::vector<std::string> kernel_case_ids();

struct KernelsRun {
  std::vector<Result> results;
  double peak_gflops = -1;  // measured device FMA peak; negative where no case needed it
};

// Runs the cases named in `only` (all but the full-only ones when empty, or
// all with `full`), logging "PREFIX: case..." to stderr before each. Throws
// std::invalid_argument for an unknown id.
KernelsRun run_kernel_cases(const Device& device, const std::vector<std::string>& only, bool full,
                            const std::string& log_prefix);

// The table title, the table, and the JSON (bench::to_json plus the peak).
void print_kernels_table(const Device& device, const KernelsRun& run);
nlohmann::json kernels_json(const Device& device, const KernelsRun& run);

}  // namespace vkjr2::bench
