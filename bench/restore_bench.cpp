// vkjr2 bench restore (this program, restore_bench, run by `vkjr2 bench restore`): the JR²
// restorer (jr2/restorer.hpp) on the device: restored frames/s at 160² (batch 1 inference) and
// training steps/s (forward + Charbonnier loss + backward + Adam), each with its GFLOP/s and its
// fraction of the device's FMA peak, and the device memory of a training step; against the same
// network in PyTorch on the CPU (tools/restorer_torch.py bench), run after ours on the same cores.
#include <vkjr2/jr2/restore_train.hpp>
#include <vkjr2/jr2/restorer.hpp>
#include <vkjr2/nets/autograd.hpp>
#include <vkjr2/nets/ops.hpp>
#include <vkjr2/nets/optimizer.hpp>
#include <vkjr2/runtime/device.hpp>
#include <vkjr2/runtime/error.hpp>
#include <vkjr2/runtime/stream.hpp>

#include <CLI/CLI.hpp>
#include <nlohmann/json.hpp>
#include <sys/wait.h>
#include <unistd.h>

#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <random>
#include <string>
#include <vector>

#include "cli/checks.hpp"
#include "cli/log.hpp"
#include "cli/run.hpp"
#include "harness.hpp"
#include "torch_peer.hpp"

#ifndef VKJR2_SOURCE_DIR
#define VKJR2_SOURCE_DIR "."
#endif

namespace vkjr2::cli {
namespace {

namespace fs = std::filesystem;
using nlohmann::json;

// The goals (docs/restoration.md's budget; bench/RESULTS.md's table).
constexpr double kPeakGoal = 0.20;   // of the device FMA peak, inference and training
constexpr double kTorchGoal = 0.50;  // vkjr2 / PyTorch on the CPU, on lavapipe

struct BenchRestoreArgs {
  int frames = 8, width = 16, middle = 1, size = 160;
  int train_size = jr2::RestoreTrainOptions{}.crop, batch = jr2::RestoreTrainOptions{}.batch;
  int repeat = 5;
  std::string enc = "1,1,1", dec = "1,1,1", device, json_path;
  TorchPeerOptions peer{.script = std::string(VKJR2_SOURCE_DIR) + "/tools/restorer_torch.py"};
  bool json_out = false;
};

std::vector<float> uniform(std::int64_t n, std::uint32_t seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<float> u(0.f, 1.f);
  std::vector<float> v(static_cast<std::size_t>(n));
  for (float& x : v) x = u(rng);
  return v;
}

std::string join(const std::vector<int>& v) {
  std::string s;
  for (int x : v) s += (s.empty() ? "" : ",") + std::to_string(x);
  return s;
}

double mib(std::uint64_t bytes) { return double(bytes) / (1024.0 * 1024.0); }

// The PyTorch peer: tools/restorer_torch.py bench times inference and one
// training step of the same network at one batch and size, and prints JSON.
nlohmann::json run_torch(TorchPeer& peer, const BenchRestoreArgs& a, int size, int batch) {
  const std::string args =
      " bench --frames " + std::to_string(a.frames) + " --width " + std::to_string(a.width) +
      " --enc " + a.enc + " --middle " + std::to_string(a.middle) + " --dec " + a.dec + " --size " +
      std::to_string(size) + " --batch " + std::to_string(batch) + " --threads " +
      std::to_string(a.peer.threads) + " --repeat " + std::to_string(a.repeat);
  return peer.run("bench restore", args, args, {"infer_s", "train_step_s"});
}

std::string met(bool ok) { return ok ? "met" : "not met"; }

void run_bench_restore(BenchRestoreArgs& a) {
  // Benchmark results are replaced; the folder must be there before the work.
  if (!a.json_path.empty()) check_output_file(a.json_path, true, "--json-file");
  jr2::RestorerConfig config;
  config.frames = a.frames;
  config.width = a.width;
  config.middle_blocks = a.middle;
  try {
    config.enc_blocks = jr2::parse_block_list(a.enc, "--enc-blocks");
    config.dec_blocks = jr2::parse_block_list(a.dec, "--dec-blocks");
    config.validate();
  } catch (const InvalidArgument& e) {
    throw UsageError("bench restore", e.problem(), e.fix());
  }
  a.enc = join(config.enc_blocks);  // as the PyTorch peer reads them
  a.dec = join(config.dec_blocks);
  const int multiple = 1 << config.levels();
  for (const auto& [option, side] :
       {std::pair{"--size", a.size}, std::pair{"--train-size", a.train_size}}) {
    if (side % multiple != 0) {
      throw UsageError(option,
                       std::to_string(side) + " is not a multiple of " + std::to_string(multiple) +
                           " (2^levels: " + std::to_string(config.levels()) + " encoder levels)",
                       "pass a multiple of " + std::to_string(multiple) +
                           ", so that both peers run the same shapes unpadded");
    }
  }
  TorchPeer torch(a.peer);
  const Device device = open_device(a.device);
  const std::int64_t t3 = 3LL * config.frames;
  const double infer_flops = config.flops(a.size, a.size);
  // Training: forward, backward to the activations and to the weights, each
  // about one forward's multiply-adds; the loss and the Adam step are not counted.
  const double train_flops = 3.0 * a.batch * config.flops(a.train_size, a.train_size);

  std::fprintf(stderr, "bench restore: device FMA peak (shaders/bench_fma.comp) ...\n");
  const double peak = bench::device_fma_gflops(device);

  Stream stream(device);
  double infer_s = 0;
  {
    std::fprintf(stderr, "bench restore: inference, %d² batch 1, 1 warm-up + %d runs ...\n", a.size,
                 a.repeat);
    jr2::Restorer net(device, config, 1);
    const Tensor x =
        Tensor::from(device, Shape{1, t3, a.size, a.size}, uniform(t3 * a.size * a.size, 2));
    infer_s = bench::median_seconds(
        [&] {
          nets::Tape tape(stream, false);
          const nets::Var y = net.forward(tape, nets::Var(x));
          stream.run();
        },
        a.repeat, 1);
  }

  // Before the training objects: what stays allocated through the run.
  const MemoryStats before = device.memory_stats();
  double train_s = 0;
  MemoryStats step_mem;
  {
    std::fprintf(stderr, "bench restore: training step, %d² batch %d, 1 warm-up + %d runs ...\n",
                 a.train_size, a.batch, a.repeat);
    jr2::Restorer net(device, config, 1);
    nets::Adam adam(net.named_parameters(), {.lr = 1e-3f});
    const std::int64_t px = std::int64_t(a.train_size) * a.train_size;
    const Tensor frames = Tensor::from(device, Shape{a.batch, t3, a.train_size, a.train_size},
                                       uniform(a.batch * t3 * px, 3));
    const Tensor clean = Tensor::from(device, Shape{a.batch, 3, a.train_size, a.train_size},
                                      uniform(a.batch * 3 * px, 4));
    train_s = bench::median_seconds(
        [&] {
          nets::Tape tape(stream);
          const nets::Var out = net.forward(tape, nets::Var(frames));
          const nets::Var loss = nets::charbonnier_loss(tape, out, nets::Var(clean), 1e-3f);
          tape.backward(loss);
          adam.step(stream);
          adam.zero_grad();
          // Nothing is released before the stream's work has finished (it
          // holds every tensor it uses): now is the step's peak.
          step_mem = device.memory_stats();
          stream.run();
        },
        a.repeat, 1);
  }

  json torch_infer, torch_train;
  if (torch.available) {
    // The memory ours keeps for reuse goes back first: the peer runs beside an idle process.
    device.release_cached_memory();
    std::fprintf(stderr, "bench restore: PyTorch peer, inference %d² batch 1 ...\n", a.size);
    torch_infer = run_torch(torch, a, a.size, 1);
    std::fprintf(stderr, "bench restore: PyTorch peer, training step %d² batch %d ...\n",
                 a.train_size, a.batch);
    torch_train = run_torch(torch, a, a.train_size, a.batch);
  }
  const double torch_infer_s = torch.available ? torch_infer.at("infer_s").get<double>() : 0;
  const double torch_train_s = torch.available ? torch_train.at("train_step_s").get<double>() : 0;

  const double infer_gflops = infer_flops / infer_s * 1e-9;
  const double train_gflops = train_flops / train_s * 1e-9;
  const std::string torch_name = torch.available
                                     ? "PyTorch CPU, " + std::to_string(a.peer.threads) + " threads"
                                     : "PyTorch (unavailable)";
  const std::string size_tag = std::to_string(a.size) + "²";
  const std::string train_tag = std::to_string(a.train_size) + "²";
  std::vector<bench::Result> rows;
  rows.push_back({"restore infer " + size_tag + " T=" + std::to_string(config.frames) + " batch 1",
                  1 / infer_s, "frames/s", torch_name, torch.available ? 1 / torch_infer_s : 0});
  rows.back().fraction_of_device_peak = infer_gflops / peak;
  rows.push_back({"restore train step " + train_tag + " batch " + std::to_string(a.batch),
                  1 / train_s, "steps/s", torch_name, torch.available ? 1 / torch_train_s : 0});
  rows.back().fraction_of_device_peak = train_gflops / peak;
  const double infer_ratio = rows[0].ratio_vs_peer(), train_ratio = rows[1].ratio_vs_peer();

  bench::print_table("vkjr2 bench restore — the JR² restorer against PyTorch on the CPU", device,
                     rows);
  const bool lavapipe = device.info().driver_id == VK_DRIVER_ID_MESA_LLVMPIPE;
  const auto ratio_text = [&](double r) {
    char s[32] = "n/a";
    if (torch.available) std::snprintf(s, sizeof s, "%.2fx", r);
    return std::string(s);
  };
  std::printf(
      "\nrestorer: T=%d, width %d, enc %s, middle %d, dec %s: %lld parameters, %.3f GFLOP per %d² "
      "forward\n"
      "device FMA peak (shaders/bench_fma.comp): %.1f GFLOP/s\n"
      "training at %d² (%s), batch %d: forward + Charbonnier loss + backward + Adam step + "
      "stream.run();\n"
      "  counted as 3x the forward's FLOPs (%.3f GFLOP per step; loss and Adam not counted)\n\n",
      config.frames, config.width, a.enc.c_str(), config.middle_blocks, a.dec.c_str(),
      static_cast<long long>(config.parameter_count()), infer_flops * 1e-9, a.size, peak,
      a.train_size,
      a.train_size == jr2::RestoreTrainOptions{}.crop ? "the shipped training crop"
                                                      : "not the shipped training crop (64²)",
      a.batch, train_flops * 1e-9);
  std::printf("%-30s %10s %12s %9s %8s %12s %14s\n", "", "vkjr2 s", "rate", "GFLOP/s", "of peak",
              "PyTorch s", "vkjr2/PyTorch");
  const auto line = [&](const std::string& name, double s, double rate, const char* unit,
                        double gflops, double torch_s, double ratio) {
    char rate_text[32], torch_text[32] = "n/a";
    std::snprintf(rate_text, sizeof rate_text, "%.3f %s", rate, unit);
    if (torch.available) std::snprintf(torch_text, sizeof torch_text, "%.4f", torch_s);
    std::printf("%-30s %10.4f %12s %9.2f %7.1f%% %12s %14s\n", name.c_str(), s, rate_text, gflops,
                100 * gflops / peak, torch_text, ratio_text(ratio).c_str());
  };
  line("inference " + size_tag + ", batch 1", infer_s, 1 / infer_s, "fr/s", infer_gflops,
       torch_infer_s, infer_ratio);
  line("training step " + train_tag + ", batch " + std::to_string(a.batch), train_s, 1 / train_s,
       "st/s", train_gflops, torch_train_s, train_ratio);
  std::printf(
      "\npeak device memory of a training step (%s, batch %d): %.1f MiB in use, %.1f MiB "
      "reserved\n"
      "  (Device::memory_stats() at the end of the step's recording, when the stream holds every "
      "tensor\n"
      "  of the step: the runtime keeps no peak counter; before the step's network: %.1f MiB in "
      "use)\n",
      train_tag.c_str(), a.batch, mib(step_mem.used_bytes), mib(step_mem.reserved_bytes),
      mib(before.used_bytes));
  const bool infer_peak_ok = infer_gflops / peak >= kPeakGoal;
  const bool train_peak_ok = train_gflops / peak >= kPeakGoal;
  std::printf(
      "\ngoals:\n  >= %.0f %% of the device FMA peak: inference %.1f %% %s, training %.1f %% %s\n",
      100 * kPeakGoal, 100 * infer_gflops / peak, met(infer_peak_ok).c_str(),
      100 * train_gflops / peak, met(train_peak_ok).c_str());
  if (!lavapipe) {
    std::printf("  >= %.1fx PyTorch on lavapipe: not this device (inference %s, training %s)\n",
                kTorchGoal, ratio_text(infer_ratio).c_str(), ratio_text(train_ratio).c_str());
  } else if (!torch.available) {
    std::printf("  >= %.1fx PyTorch on lavapipe: n/a (no PyTorch peer)\n", kTorchGoal);
  } else {
    std::printf("  >= %.1fx PyTorch on lavapipe: inference %s %s, training %s %s\n", kTorchGoal,
                ratio_text(infer_ratio).c_str(), met(infer_ratio >= kTorchGoal).c_str(),
                ratio_text(train_ratio).c_str(), met(train_ratio >= kTorchGoal).c_str());
  }
  std::printf(
      "\nmedian of %d runs after 1 warm-up, the peers timed one after the other (ours first).\n",
      a.repeat);
  if (torch.available) {
    std::printf("PyTorch peer: torch %s, %d threads (%s ...)\n",
                torch_infer.value("torch", std::string("?")).c_str(), a.peer.threads,
                (a.peer.python + " " + a.peer.script + " bench").c_str());
  } else {
    std::printf("PyTorch peer: %s\n", torch.reason.c_str());
  }

  json out = bench::to_json(device, rows);
  out["config"] = {{"frames", config.frames},         {"width", config.width},
                   {"enc_blocks", config.enc_blocks}, {"middle_blocks", config.middle_blocks},
                   {"dec_blocks", config.dec_blocks}, {"parameters", config.parameter_count()}};
  out["device_fma_gflops"] = peak;
  out["repeat"] = a.repeat;
  out["inference"] = {{"size", a.size},
                      {"batch", 1},
                      {"seconds", infer_s},
                      {"frames_per_s", 1 / infer_s},
                      {"gflop", infer_flops * 1e-9},
                      {"gflops", infer_gflops},
                      {"fraction_of_device_peak", infer_gflops / peak}};
  out["training"] = {{"size", a.train_size},
                     {"batch", a.batch},
                     {"seconds_per_step", train_s},
                     {"steps_per_s", 1 / train_s},
                     {"gflop_per_step", train_flops * 1e-9},
                     {"flops_counted_as", "3x forward"},
                     {"gflops", train_gflops},
                     {"fraction_of_device_peak", train_gflops / peak},
                     {"memory",
                      {{"used_bytes", step_mem.used_bytes},
                       {"reserved_bytes", step_mem.reserved_bytes},
                       {"used_bytes_before", before.used_bytes},
                       {"source", "Device::memory_stats() at the end of the step's recording"}}}};
  if (torch.available) {
    out["torch"] = {{"inference", torch_infer},
                    {"training", torch_train},
                    {"ratio_inference", infer_ratio},
                    {"ratio_training", train_ratio}};
  } else {
    out["torch"] = torch.reason;
  }
  out["goals"] = {{"fraction_of_device_peak", kPeakGoal},
                  {"inference_peak_met", infer_peak_ok},
                  {"training_peak_met", train_peak_ok},
                  {"ratio_vs_torch_on_lavapipe", kTorchGoal}};
  if (lavapipe && torch.available) {
    out["goals"]["inference_torch_met"] = infer_ratio >= kTorchGoal;
    out["goals"]["training_torch_met"] = train_ratio >= kTorchGoal;
  }
  bench::emit_json(out, a.json_path, a.json_out);
}

}  // namespace
}  // namespace vkjr2::cli

namespace {

int run(int argc, char** argv) {
  using namespace vkjr2::cli;
  CLI::App app{
      "The JR² restorer's inference frames/s and training steps/s against PyTorch on the CPU",
      "vkjr2 bench restore"};
  add_logging_options(app);
  BenchRestoreArgs a;
  app.footer(
      "Times the restorer (a fresh network of the given configuration, random inputs) on the "
      "device:\n"
      "inference of one --size² clip of T frames, and one training step at --batch and "
      "--train-size\n"
      "(forward + Charbonnier loss + backward + Adam); prints frames/s and steps/s, their GFLOP/s "
      "and\n"
      "fraction of the device FMA peak, the training step's device memory, and the same network "
      "in\n"
      "PyTorch on the CPU (tools/restorer_torch.py bench, --threads threads), timed after ours.\n"
      "Example:\n  vkjr2 bench restore --json-file bench_restore.json\n"
      "The other benchmarks: vkjr2 bench --help (bench/RESULTS.md has the latest figures).");
  app.add_option("--frames", a.frames, "Input frames T")
      ->default_val(a.frames)
      ->check(integer_range(1, 64));
  app.add_option("--width", a.width, "Channels at full resolution")
      ->default_val(a.width)
      ->check(integer_range(2, 256));
  app.add_option("--enc-blocks", a.enc, "NAFBlocks per encoder level")->default_val(a.enc);
  app.add_option("--middle-blocks", a.middle, "NAFBlocks at the bottom")
      ->default_val(a.middle)
      ->check(integer_range(0, 32));
  app.add_option("--dec-blocks", a.dec, "NAFBlocks per decoder level, deepest first")
      ->default_val(a.dec);
  app.add_option("--size", a.size, "Inference frame side in pixels")
      ->default_val(a.size)
      ->check(integer_range(16, 2048));
  app.add_option("--train-size", a.train_size,
                 "Training clip side in pixels (default: restore-train's --crop)")
      ->default_val(a.train_size)
      ->check(integer_range(16, 512));
  app.add_option("--batch", a.batch, "Clips per training step")
      ->default_val(a.batch)
      ->check(integer_range(1, 256));
  app.add_option("--repeat", a.repeat, "Timed runs of each (median), after one warm-up")
      ->default_val(a.repeat)
      ->check(integer_range(1, 1000));
  add_torch_peer_options(app, a.peer);
  app.add_option("--device", a.device, "Vulkan device index or name substring (else VKJR2_DEVICE)");
  app.add_option("--json-file", a.json_path, "Also write the results as JSON here");
  app.add_flag("--json", a.json_out, "Print the JSON after the table");
  app.callback([&a] { run_bench_restore(a); });
  return run_program(app, argc, argv);
}

}  // namespace

int main(int argc, char** argv) { return vkjr2::cli::program_main(argc, argv, run); }
