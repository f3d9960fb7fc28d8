// Shared benchmark plumbing: timing, a printed table and JSON output. Every
// figure is compared with a peer measured in the same run.
#pragma once

#include <vkjr2/runtime/stream.hpp>

#include <nlohmann/json.hpp>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <fstream>
#include <functional>
#include <string>
#include <thread>
#include <vector>

namespace vkjr2::bench {

struct Result {
  std::string name;
  double value = 0;
  std::string unit;
  std::string peer;
  double peer_value = 0;
  // Compute-bound kernels: value / measured device peak (negative: not applicable).
  double fraction_of_device_peak = -1;
  bool higher_is_better = true;

  double ratio_vs_peer() const {
    if (peer_value == 0 || value == 0) return 0;
    return higher_is_better ? value / peer_value : peer_value / value;
  }
};

// Wall time of one call of `fn`, in seconds.
inline double seconds_of(const std::function<void()>& fn) {
  const auto start = std::chrono::steady_clock::now();
  fn();
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
}

// Median wall time of `fn` in seconds over `reps` runs after `warmup` runs.
inline double median_seconds(const std::function<void()>& fn, int reps, int warmup = 1) {
  for (int i = 0; i < warmup; ++i) fn();
  std::vector<double> t;
  for (int i = 0; i < reps; ++i) t.push_back(seconds_of(fn));
  std::sort(t.begin(), t.end());
  return t[t.size() / 2];
}

inline std::string machine_name() {
  std::ifstream cpu("/proc/cpuinfo");
  std::string line;
  while (std::getline(cpu, line)) {
    if (line.rfind("model name", 0) == 0) {
      return line.substr(line.find(':') + 2) + ", " +
             std::to_string(std::thread::hardware_concurrency()) + " threads";
    }
  }
  return "unknown CPU";
}

// Peak fp32 FMA throughput of the device (shaders/bench_fma.comp), GFLOP/s:
// what compute-bound kernels report their fraction of.
inline double device_fma_gflops(const Device& dev) {
  struct FmaPush {
    std::uint32_t iterations;
    float a;
    float b;
  };
  static const KernelDef kFma{"bench_fma", {BindingKind::storage}, sizeof(FmaPush)};
  constexpr std::uint32_t kGroups = 256, kLocal = 64, kIters = 512;
  Tensor result = Tensor::empty(dev, {kGroups * kLocal * 4});
  Stream s(dev);
  const double sec = median_seconds(
      [&] {
        s.dispatch(kFma, {out(result)}, FmaPush{kIters, 0.999f, 1e-4f}, Groups{kGroups});
        s.run();
      },
      5);
  const double flops = 2.0 * kGroups * kLocal * kIters * 4 /*unroll*/ * 16 /*chains*/ * 4 /*vec4*/;
  return flops / sec * 1e-9;
}

inline void print_table(const std::string& title, const Device& device,
                        const std::vector<Result>& results) {
  std::printf("%s\ndevice: %s (%s)\nmachine: %s\n\n", title.c_str(), device.info().name.c_str(),
              device.info().driver_info.c_str(), machine_name().c_str());
  // Columns as wide as their longest entry (at least the headers' usual widths).
  int name_w = 34, peer_w = 30;
  for (const Result& r : results) {
    name_w = std::max(name_w, static_cast<int>(r.name.size()));
    peer_w = std::max(peer_w, static_cast<int>(r.peer.size()));
  }
  std::printf("%-*s %12s %-9s %-*s %12s %8s %7s\n", name_w, "benchmark", "value", "unit", peer_w,
              "peer", "peer value", "ratio", "of peak");
  for (const Result& r : results) {
    char peak[16] = "";
    if (r.fraction_of_device_peak >= 0) {
      std::snprintf(peak, sizeof peak, "%5.1f%%", 100 * r.fraction_of_device_peak);
    }
    std::printf("%-*s %12.3f %-9s %-*s %12.3f %7.3fx %7s\n", name_w, r.name.c_str(), r.value,
                r.unit.c_str(), peer_w, r.peer.c_str(), r.peer_value, r.ratio_vs_peer(), peak);
  }
  std::printf("\nratio > 1: vkjr2 is better than the peer (throughput higher or time lower)\n");
}

inline nlohmann::json to_json(const Device& device, const std::vector<Result>& results) {
  nlohmann::json out;
  out["device"] = device.info().name;
  out["driver"] = device.info().driver_info;
  out["machine"] = machine_name();
  out["results"] = nlohmann::json::array();
  for (const Result& r : results) {
    nlohmann::json j = {
        {"name", r.name}, {"value", r.value},           {"unit", r.unit},
        {"peer", r.peer}, {"peer_value", r.peer_value}, {"ratio_vs_peer", r.ratio_vs_peer()}};
    if (r.fraction_of_device_peak >= 0) j["fraction_of_device_peak"] = r.fraction_of_device_peak;
    out["results"].push_back(j);
  }
  return out;
}

// Writes JSON atomically (temporary name, then rename).
inline void write_json(const std::string& path, const nlohmann::json& j) {
  const std::string tmp = path + ".tmp";
  {
    std::ofstream f(tmp);
    f << j.dump(2) << "\n";
    if (!f) throw std::runtime_error("cannot write " + tmp);
  }
  if (std::rename(tmp.c_str(), path.c_str()) != 0) {
    throw std::runtime_error("cannot rename " + tmp + " to " + path);
  }
}

// The end of every benchmark run: the JSON written to `path` (when given)
// and printed after the table (with --json).
inline void emit_json(const nlohmann::json& j, const std::string& path, bool print) {
  if (!path.empty()) write_json(path, j);
  if (print) std::printf("%s\n", j.dump(2).c_str());
}

}  // namespace vkjr2::bench
