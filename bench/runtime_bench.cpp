// runtime_bench: the cost of the runtime itself on this device — dispatch
// overhead, memory bandwidth and FMA throughput — each against a peer
// measured in the same run (plain C++ on the same cores).
#include <vkjr2/kernels/basic.hpp>
#include <vkjr2/runtime/stream.hpp>

#include <cstring>
#include <iostream>
#include <thread>

#include "harness.hpp"

namespace vkjr2 {
namespace {

// Dispatch overhead: one tiny dispatch per submit vs 100 in one command buffer.
std::vector<bench::Result> dispatch_overhead(const Device& dev) {
  std::vector<Tensor> tiny;
  for (int i = 0; i < 100; ++i) tiny.push_back(Tensor::empty(dev, {1}));
  Stream s(dev);
  const double one = bench::median_seconds(
                         [&] {
                           for (int i = 0; i < 20; ++i) {
                             kernels::fill(s, tiny[0], 1.f);
                             s.run();
                           }
                         },
                         5) /
                     20;
  const double batched = bench::median_seconds(
                             [&] {
                               for (const Tensor& t : tiny)
                                 kernels::fill(s, t, 1.f);  // independent: no barriers
                               s.run();
                             },
                             5) /
                         100;
  // Recording alone (host time, nothing submitted): what vkjr2 adds on the
  // CPU per dispatch, against the per-dispatch execution cost above.
  for (const Tensor& t : tiny) kernels::fill(s, t, 1.f);  // warm: pipeline, vectors
  s.run();
  const double recording = bench::median_seconds(
                               [&] {
                                 for (int round = 0; round < 10; ++round) {
                                   for (const Tensor& t : tiny) kernels::fill(s, t, 1.f);
                                 }
                               },
                               5) /
                           1000;
  s.run();
  bench::Result rec;
  rec.name = "dispatch recording (host), per dispatch";
  rec.value = recording * 1e6;
  rec.unit = "us";
  rec.peer = "execution, 100 per command buffer";
  rec.peer_value = batched * 1e6;
  rec.higher_is_better = false;
  bench::Result r;
  r.name = "dispatch, 100 per command buffer";
  r.value = batched * 1e6;
  r.unit = "us";
  r.peer = "1 dispatch per submit+wait";
  r.peer_value = one * 1e6;
  r.higher_is_better = false;
  return {r, rec};
}

std::vector<bench::Result> copy_bandwidth(const Device& dev) {
  const std::int64_t n = 16 << 20;  // 64 MiB of floats
  const double bytes = double(n) * 4;
  Tensor a = Tensor::empty(dev, {n}), b = Tensor::empty(dev, {n});
  Stream s(dev);
  kernels::fill(s, a, 1.f);
  s.run();
  const double kernel_s = bench::median_seconds(
      [&] {
        kernels::copy(s, a, b);
        s.run();
      },
      7);
  const double transfer_s = bench::median_seconds(
      [&] {
        s.copy(a, b);
        s.run();
      },
      7);
  std::vector<float> x(static_cast<std::size_t>(n), 1.f);
  std::vector<float> y(static_cast<std::size_t>(n));
  const double memcpy_s =
      bench::median_seconds([&] { std::memcpy(y.data(), x.data(), x.size() * sizeof(float)); }, 7);
  const double peer = bytes / memcpy_s * 1e-9;
  bench::Result k{"copy kernel 64 MiB", bytes / kernel_s * 1e-9, "GB/s", "memcpy (1 thread)", peer};
  bench::Result t{"vkCmdCopyBuffer 64 MiB", bytes / transfer_s * 1e-9, "GB/s", "memcpy (1 thread)",
                  peer};
  return {k, t};
}

// Plain C++ FMA peak on all cores: independent chains the compiler vectorizes.
double cpu_fma_gflops(unsigned threads) {
  constexpr int kChains = 128;
  constexpr long kIters = 4'000'000;
  auto worker = [](float seed, float* out) {
    alignas(64) float acc[kChains];
    for (int j = 0; j < kChains; ++j) acc[j] = seed + float(j);
    const float a = 0.999f, b = 1e-4f;
    for (long i = 0; i < kIters; ++i) {
      for (int j = 0; j < kChains; ++j) acc[j] = acc[j] * a + b;
    }
    float s = 0;
    for (int j = 0; j < kChains; ++j) s += acc[j];
    *out = s;
  };
  std::vector<float> sink(threads);
  const double sec = bench::median_seconds(
      [&] {
        std::vector<std::thread> pool;
        for (unsigned t = 0; t < threads; ++t) pool.emplace_back(worker, float(t), &sink[t]);
        for (auto& th : pool) th.join();
      },
      3);
  if (sink[0] == 12345.f) std::printf(" ");  // keep the result alive
  return 2.0 * kChains * double(kIters) * threads / sec * 1e-9;
}

std::vector<bench::Result> fma_throughput(const Device& dev, double* device_peak) {
  const double gflops = bench::device_fma_gflops(dev);
  *device_peak = gflops;
  const unsigned threads = std::max(1u, std::thread::hardware_concurrency());
  bench::Result r{"FMA fp32 throughput", gflops, "GFLOP/s",
                  "C++ FMA, " + std::to_string(threads) + " threads", cpu_fma_gflops(threads)};
  r.fraction_of_device_peak = 1.0;  // this is the device peak others are measured against
  return {r};
}

int run(int argc, char** argv) {
  std::string json_path = "runtime_bench.json";
  for (int i = 1; i < argc; ++i) {
    const std::string arg = argv[i];
    if (arg == "--json" && i + 1 < argc) {
      json_path = argv[++i];
    } else if (arg == "--help" || arg == "-h") {
      std::printf(
          "usage: runtime_bench [--json FILE]\n"
          "Measures dispatch overhead, copy bandwidth and FMA throughput of the Vulkan device\n"
          "(VKJR2_DEVICE picks it) against plain C++ on the same machine; prints a table and\n"
          "writes JSON (default runtime_bench.json).\n");
      return 0;
    } else {
      std::fprintf(stderr, "runtime_bench: unknown argument '%s' (try --help)\n", arg.c_str());
      return 2;
    }
  }
  DeviceOptions options;
  options.validation = false;  // benchmarks measure the driver, not the layer
  const Device dev(options);
  std::vector<bench::Result> results;
  double peak = 0;
  for (auto& r : dispatch_overhead(dev)) results.push_back(r);
  for (auto& r : copy_bandwidth(dev)) results.push_back(r);
  for (auto& r : fma_throughput(dev, &peak)) results.push_back(r);
  bench::print_table("vkjr2 runtime_bench", dev, results);
  bench::write_json(json_path, bench::to_json(dev, results));
  std::printf("wrote %s\n", json_path.c_str());
  return 0;
}

}  // namespace
}  // namespace vkjr2

int main(int argc, char** argv) {
  try {
    return vkjr2::run(argc, argv);
  } catch (const std::exception& e) {
    std::fprintf(stderr, "runtime_bench: error: %s\n", e.what());
    return 1;
  }
}
