// vkjr2 bench cotrain (this program, cotrain_bench, run by `vkjr2 bench cotrain`): one JR²
// co-training step (jr2/cotrain.hpp, restore-first) on the device, timed stage by stage, with the
// device memory it holds; against the same graph in PyTorch on the CPU (tools/cotrain_torch.py
// bench), run after ours on the same cores.
//
// The graph, built here from the nets ops with stream.run() after each stage (its wall time):
//   student    out = R_s(y), y [B, 3T, W, W] in 0..1 (recorded for backward)
//   teacher    target = R_t(y) (not recorded)
//   align + recognizer + head
//              pixels = 255·(relu(out) − relu(out − 1)); crops = grid_sample(pixels,
//              affine_grid(theta, 150²)); d = G(crops) (face-api's recognizer, frozen);
//              L = CE(AdaFace(d), labels) + λ·mean |out − target|
//   backward   to the student's parameters and the head's class centres
//   optimizer  Adam step, zero_grad
// theta [B, 2, 3] are constants (in `vkjr2 cotrain` they come from landmarks on the host): a
// seeded small rotation and scale about a centred face, passed to the peer as they are. The
// landmarks stage CoTrainer runs between them (68 landmarks per clip → 5 points → similarity →
// theta) is timed separately, on our side only, outside the step.
#include <vkjr2/jr2/align.hpp>
#include <vkjr2/jr2/cotrain.hpp>
#include <vkjr2/jr2/restorer.hpp>
#include <vkjr2/nets/adaface.hpp>
#include <vkjr2/nets/autograd.hpp>
#include <vkjr2/nets/face_landmarks.hpp>
#include <vkjr2/nets/face_recognition.hpp>
#include <vkjr2/nets/ops.hpp>
#include <vkjr2/nets/optimizer.hpp>
#include <vkjr2/runtime/device.hpp>
#include <vkjr2/runtime/error.hpp>
#include <vkjr2/runtime/stream.hpp>

#include <CLI/CLI.hpp>
#include <nlohmann/json.hpp>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <numbers>
#include <random>
#include <string>
#include <utility>
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
using nets::Var;
using nlohmann::json;

constexpr double kTorchGoal = 0.50;  // vkjr2 / PyTorch on the CPU, on lavapipe (steps/s)
constexpr std::int64_t kCrop = nets::kRecognitionInputSize;  // 150
constexpr std::int64_t kDescriptor = nets::FaceRecognitionNet::kDescriptorSize;

struct BenchCotrainArgs {
  int batch = jr2::CoTrainOptions{}.batch, window = jr2::CoTrainOptions{}.window, classes = 19;
  float lambda = jr2::CoTrainOptions{}.lambda, lr = jr2::CoTrainOptions{}.lr;
  int repeat = 5;
  std::uint32_t seed = 1;
  std::string restorer, device, json_path;
  TorchPeerOptions peer{.script = std::string(VKJR2_SOURCE_DIR) + "/tools/cotrain_torch.py"};
  bool json_out = false;
};

// The stages of a step, in order (the JSON keys the PyTorch peer uses).
constexpr std::array<const char*, 5> kStageKeys{"student", "teacher", "align_recognize_head",
                                                "backward", "optimizer"};
constexpr std::array<const char*, 5> kStageNames{"student forward", "teacher forward",
                                                 "align + recognizer + head fwd", "backward",
                                                 "optimizer (Adam)"};

std::vector<float> uniform(std::int64_t n, std::uint32_t seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<float> u(0.f, 1.f);
  std::vector<float> v(static_cast<std::size_t>(n));
  for (float& x : v) x = u(rng);
  return v;
}

double mib(std::uint64_t bytes) { return double(bytes) / (1024.0 * 1024.0); }

double median(std::vector<double> v) {
  std::sort(v.begin(), v.end());
  return v[v.size() / 2];
}

double seconds_since(std::chrono::steady_clock::time_point t0) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
}

// theta [B, 2, 3] (affine_grid, align_corners = false) of 150² crops of a face centred in the
// window: per clip the crop → window similarity turns by up to ±10°, spans 0.8·W (× 0.9..1.1)
// and puts the crop's centre within ±4 px of the window's (tools/cotrain_torch.py has the same
// recipe for when it runs alone).
std::vector<float> make_thetas(int batch, int window, std::uint32_t seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  const auto in = [&](double lo, double hi) { return lo + (hi - lo) * u(rng); };
  std::vector<float> thetas;
  for (int b = 0; b < batch; ++b) {
    const double angle = in(-10, 10) * std::numbers::pi / 180;
    const double scale = 0.8 * window / double(kCrop) * in(0.9, 1.1);
    const double cx = (window - 1) / 2.0 + in(-4, 4), cy = (window - 1) / 2.0 + in(-4, 4);
    const double a = scale * std::cos(angle), s = scale * std::sin(angle);
    const double c = double(kCrop - 1) / 2;  // the crop's centre pixel
    const jr2::Similarity crop_to_window{a, s, cx - (a * c - s * c), cy - (s * c + a * c)};
    const auto th = jr2::crop_theta(crop_to_window.inverse(), window, window, kCrop, kCrop);
    thetas.insert(thetas.end(), th.begin(), th.end());
  }
  return thetas;
}

std::string csv(const std::vector<float>& v) {
  std::string s;
  for (float x : v) {
    char b[32];
    std::snprintf(b, sizeof b, "%.9g", double(x));
    s += (s.empty() ? "" : ",") + std::string(b);
  }
  return s;
}

// The PyTorch peer: tools/cotrain_torch.py bench times the same step's
// stages (with our thetas) and prints JSON.
nlohmann::json run_torch(TorchPeer& peer, const BenchCotrainArgs& a,
                         const std::vector<float>& thetas) {
  const std::string shown_args =
      " bench --batch " + std::to_string(a.batch) + " --window " + std::to_string(a.window) +
      " --classes " + std::to_string(a.classes) + " --lambda " + std::to_string(a.lambda) +
      " --threads " + std::to_string(a.peer.threads) + " --repeat " + std::to_string(a.repeat) +
      " --seed " + std::to_string(a.seed) + " --restorer ";
  return peer.run("bench cotrain",
                  shown_args + shell_quote(a.restorer) + " --thetas " + csv(thetas),
                  shown_args + a.restorer + " --thetas ...", {"stages", "step_s"});
}

// 255 · clamp(x, 0, 1) = 255 · (relu(x) − relu(x − 1)), as CoTrainer computes it.
Var to_pixels_var(nets::Tape& t, const Var& x) {
  const Var low = nets::relu(t, x);
  const Var high = nets::relu(t, nets::scale_shift(t, x, 1.f, -1.f));
  return nets::scale_shift(t, nets::sub(t, low, high), 255.f);
}

// Per-stage wall times of the timed steps, and the device memory at the end of each stage's
// recording (the stream then holds every tensor of the stage, so the largest is the step's peak).
struct StepTimes {
  std::array<std::vector<double>, kStageKeys.size()> stage_s;
  std::vector<double> step_s;
  MemoryStats peak;
  std::size_t peak_stage = 0;
};

// The networks and tensors of the step.
struct CotrainGraph {
  const Device& device;
  Stream stream;
  std::unique_ptr<jr2::Restorer> student, teacher;
  std::unique_ptr<nets::FaceRecognitionNet> recognizer;
  std::unique_ptr<nets::AdaFaceHead> head;
  std::unique_ptr<nets::Adam> adam;
  Tensor input, theta, labels;
  float lambda;

  CotrainGraph(const Device& d, const BenchCotrainArgs& a, const std::vector<float>& thetas)
      : device(d),
        stream(d),
        student(jr2::Restorer::load(d, a.restorer)),
        teacher(jr2::Restorer::load(d, a.restorer)),
        recognizer(nets::FaceRecognitionNet::load(d)),
        head(std::make_unique<nets::AdaFaceHead>(d, int(kDescriptor), a.classes, a.seed)),
        lambda(a.lambda) {
    for (const Var& p : teacher->parameters()) p.set_requires_grad(false);
    teacher->eval();
    student->train();
    recognizer->set_frozen(true);
    head->train();
    std::vector<std::pair<std::string, Var>> trainable;
    for (auto& [name, p] : student->named_parameters())
      trainable.emplace_back("student." + name, p);
    for (auto& [name, p] : head->named_parameters()) trainable.emplace_back("head." + name, p);
    adam = std::make_unique<nets::Adam>(trainable, kernels::AdamOptions{.lr = a.lr});
    const std::int64_t t3 = 3LL * student->config().frames, w = a.window;
    input = Tensor::from(d, Shape{a.batch, t3, w, w}, uniform(a.batch * t3 * w * w, a.seed + 1));
    theta = Tensor::from(d, Shape{a.batch, 2, 3}, thetas);
    std::vector<std::int32_t> l(std::size_t(a.batch), 0);
    for (std::size_t b = 0; b < l.size(); ++b) l[b] = std::int32_t(b % std::size_t(a.classes));
    labels = Tensor::empty(d, Shape{a.batch}, DType::i32);
    labels.upload_bytes(l.data(), l.size() * sizeof(std::int32_t));
  }

  // One step; adds its stage times (when `times`) and tracks the peak memory.
  void step(StepTimes* times, StepTimes& memory) {
    std::size_t stage = 0;
    const auto t0 = std::chrono::steady_clock::now();
    auto lap = t0;
    const auto split = [&] {
      const MemoryStats m = device.memory_stats();
      if (m.used_bytes > memory.peak.used_bytes) {
        memory.peak = m;
        memory.peak_stage = stage;
      }
      stream.run();
      if (times != nullptr) times->stage_s[stage].push_back(seconds_since(lap));
      lap = std::chrono::steady_clock::now();
      ++stage;
    };
    nets::Tape tape(stream);
    const Var out = student->forward(tape, Var(input));
    split();
    Tensor target;
    {
      nets::Tape frozen(stream, false);
      target = teacher->forward(frozen, Var(input)).value();
    }
    split();
    const Var pixels = to_pixels_var(tape, out);
    const Var grid = nets::affine_grid(tape, Var(theta), kCrop, kCrop, false);
    const Var crops = nets::grid_sample(tape, pixels, grid, {kernels::SamplePadding::zeros, false});
    const Var desc = recognizer->forward(tape, crops);
    const Var logits = head->forward(tape, desc, labels);
    const Var recognition = nets::cross_entropy(tape, logits, labels);
    const Var distillation = nets::l1_loss(tape, out, Var(target));
    const Var loss = nets::add(tape, recognition, nets::scale_shift(tape, distillation, lambda));
    split();
    tape.backward(loss);
    split();
    adam->step(stream);
    adam->zero_grad();
    split();
    if (times != nullptr) times->step_s.push_back(seconds_since(t0));
    const float l = loss.value().download()[0];
    if (!std::isfinite(l)) {
      throw Error("bench cotrain", "the loss became " + std::to_string(l),
                  "this is a bug in the benchmark's graph or an op: report it");
    }
  }
};

std::string met(bool ok) { return ok ? "met" : "not met"; }

void run_bench_cotrain(BenchCotrainArgs& a) {
  // Benchmark results are replaced; the folder must be there before the work.
  if (!a.json_path.empty()) check_output_file(a.json_path, true, "--json-file");
  if (a.restorer.empty()) a.restorer = jr2::default_restorer_path().string();
  check_input_file(a.restorer, "--restorer");
  TorchPeer torch(a.peer);
  const Device device = open_device(a.device);
  const std::vector<float> thetas = make_thetas(a.batch, a.window, a.seed);

  const MemoryStats before_nets = device.memory_stats();
  CotrainGraph g(device, a, thetas);
  const jr2::RestorerConfig& config = g.student->config();
  const int multiple = 1 << config.levels();
  if (a.window % multiple != 0) {
    throw UsageError("--window",
                     std::to_string(a.window) + " is not a multiple of " +
                         std::to_string(multiple) + " (2^levels of " + a.restorer + ")",
                     "pass a multiple of " + std::to_string(multiple));
  }
  const MemoryStats before = device.memory_stats();

  std::fprintf(stderr,
               "bench cotrain: step at batch %d, window %d², T=%d, 1 warm-up + %d steps ...\n",
               a.batch, a.window, config.frames, a.repeat);
  StepTimes times;
  g.step(nullptr, times);
  device.reset_profile();  // VKJR2_PROFILE=1: the timed steps only (no JIT, no first touches)
  for (int i = 0; i < a.repeat; ++i) g.step(&times, times);
  if (device.profiling_enabled()) {
    std::fprintf(stderr, "bench cotrain: the %d timed steps, device time per kernel:\n%s", a.repeat,
                 device.profile_report().c_str());
    device.reset_profile();
  }

  // The landmarks CoTrainer finds on each restored window (a centred face box of 0.6·W), the
  // 5 points, the similarity and theta, uploaded: host work between the stages, outside the
  // compared graph.
  std::fprintf(stderr, "bench cotrain: landmarks → theta of %d clips (ours only) ...\n", a.batch);
  const auto landmark_net = nets::FaceLandmark68Net::load(device);
  const std::int64_t w = a.window;
  Tensor pixels;
  {
    nets::Tape t(g.stream, false);
    pixels = to_pixels_var(t, g.student->forward(t, Var(g.input))).value();
    g.stream.run();
  }
  const nets::FaceBox box{0.2 * double(w), 0.2 * double(w), 0.6 * double(w), 0.6 * double(w)};
  const double landmarks_s = bench::median_seconds(
      [&] {
        std::vector<float> th;
        for (std::int64_t b = 0; b < a.batch; ++b) {
          const Tensor one = pixels.view(Shape{1, 3, w, w}, b * 3 * w * w);
          const auto lm = landmark_net->landmarks_in_image(g.stream, one, box);
          const std::vector<float> lmf(lm.begin(), lm.end());
          const jr2::Similarity s =
              jr2::fit_similarity(jr2::five_points(lmf), jr2::canonical_points(int(kCrop)));
          const auto t6 = jr2::crop_theta(s, w, w, kCrop, kCrop);
          th.insert(th.end(), t6.begin(), t6.end());
        }
        const Tensor uploaded = Tensor::from(device, Shape{a.batch, 2, 3}, th);
      },
      a.repeat, 1);

  json torch_result;
  if (torch.available) {
    // The memory ours keeps for reuse goes back first: the peer runs beside an idle process.
    device.release_cached_memory();
    std::fprintf(stderr, "bench cotrain: PyTorch peer, the same step ...\n");
    torch_result = run_torch(torch, a, thetas);
  }

  std::array<double, kStageKeys.size()> ours{}, theirs{};
  for (std::size_t i = 0; i < kStageKeys.size(); ++i) {
    ours[i] = median(times.stage_s[i]);
    theirs[i] = torch.available ? torch_result.at("stages").at(kStageKeys[i]).get<double>() : 0;
  }
  const double step_s = median(times.step_s);
  const double torch_step_s = torch.available ? torch_result.at("step_s").get<double>() : 0;
  const std::string torch_name = torch.available
                                     ? "PyTorch CPU, " + std::to_string(a.peer.threads) + " threads"
                                     : "PyTorch (unavailable)";

  std::vector<bench::Result> rows;
  for (std::size_t i = 0; i < kStageKeys.size(); ++i) {
    rows.push_back({std::string("cotrain ") + kStageNames[i], 1e3 * ours[i], "ms", torch_name,
                    1e3 * theirs[i]});
    rows.back().higher_is_better = false;
  }
  rows.push_back(
      {"cotrain step batch " + std::to_string(a.batch) + " " + std::to_string(a.window) + "²",
       1 / step_s, "steps/s", torch_name, torch.available ? 1 / torch_step_s : 0});
  const double ratio = rows.back().ratio_vs_peer();

  bench::print_table("vkjr2 bench cotrain — a JR² co-training step against PyTorch on the CPU",
                     device, rows);
  const bool lavapipe = device.info().driver_id == VK_DRIVER_ID_MESA_LLVMPIPE;
  const auto ratio_text = [&](double r) {
    char s[32] = "n/a";
    if (torch.available) std::snprintf(s, sizeof s, "%.2fx", r);
    return std::string(s);
  };
  std::printf(
      "\nstep: restore-first, batch %d clips of T=%d frames, window %d² (input [%d, %d, %d, %d]), "
      "%d classes, λ = %g, Adam lr %g\n"
      "student/teacher: %s (width %d, %lld parameters each)\n"
      "theta: fixed, seeded (--seed %u): ±10° rotation, 0.8·W × 0.9..1.1 about a centred face\n\n",
      a.batch, config.frames, a.window, a.batch, 3 * config.frames, a.window, a.window, a.classes,
      double(a.lambda), double(a.lr), a.restorer.c_str(), config.width,
      static_cast<long long>(config.parameter_count()), a.seed);
  std::printf("%-32s %10s %7s %12s %14s\n", "stage", "vkjr2 ms", "share", "PyTorch ms",
              "vkjr2/PyTorch");
  const auto line = [&](const std::string& name, double s, double torch_s, double r) {
    char torch_text[32] = "n/a";
    if (torch.available) std::snprintf(torch_text, sizeof torch_text, "%.1f", 1e3 * torch_s);
    std::printf("%-32s %10.1f %6.1f%% %12s %14s\n", name.c_str(), 1e3 * s, 100 * s / step_s,
                torch_text, ratio_text(r).c_str());
  };
  for (std::size_t i = 0; i < kStageKeys.size(); ++i) {
    line(kStageNames[i], ours[i], theirs[i], rows[i].ratio_vs_peer());
  }
  line("step (median of the totals)", step_s, torch_step_s, ratio);
  std::printf("%-32s %10.1f %7s %12s %14s\n", "landmarks → theta (not in step)", 1e3 * landmarks_s,
              "", "-", "-");
  std::printf("steps/s: vkjr2 %.3f, PyTorch %s\n", 1 / step_s,
              torch.available ? std::to_string(1 / torch_step_s).c_str() : "n/a");
  std::printf(
      "\npeak device memory of a step: %.1f MiB in use, %.1f MiB reserved (at the end of the %s "
      "stage)\n"
      "  (Device::memory_stats() at the end of each stage's recording, when the stream holds every "
      "tensor\n"
      "  of the stage: the runtime keeps no peak counter; networks, Adam state and inputs: %.1f "
      "MiB in use)\n",
      mib(times.peak.used_bytes), mib(times.peak.reserved_bytes), kStageNames[times.peak_stage],
      mib(before.used_bytes - before_nets.used_bytes));
  if (torch.available && torch_result.contains("max_rss_bytes")) {
    std::printf("PyTorch process peak resident memory (host, all of it): %.1f MiB\n",
                mib(torch_result["max_rss_bytes"].get<std::uint64_t>()));
  }
  std::printf("\ngoal:\n");
  if (!lavapipe) {
    std::printf("  >= %.1fx PyTorch on lavapipe: not this device (%s)\n", kTorchGoal,
                ratio_text(ratio).c_str());
  } else if (!torch.available) {
    std::printf("  >= %.1fx PyTorch on lavapipe: n/a (no PyTorch peer)\n", kTorchGoal);
  } else {
    std::printf("  >= %.1fx PyTorch on lavapipe: %s %s\n", kTorchGoal, ratio_text(ratio).c_str(),
                met(ratio >= kTorchGoal).c_str());
  }
  std::printf(
      "\nmedian of %d steps after 1 warm-up, the peers timed one after the other (ours first);\n"
      "not in either step: the data pool (simulator), gradient-norm clipping, the LR schedule.\n",
      a.repeat);
  if (torch.available) {
    std::printf(
        "PyTorch peer: torch %s, %d threads, the restorer's weights from the same file, "
        "recognizer float32 (%s)\n",
        torch_result.value("torch", std::string("?")).c_str(), a.peer.threads,
        (a.peer.python + " " + a.peer.script + " bench").c_str());
  } else {
    std::printf("PyTorch peer: %s\n", torch.reason.c_str());
  }

  json out = bench::to_json(device, rows);
  out["config"] = {{"batch", a.batch},
                   {"frames", config.frames},
                   {"window", a.window},
                   {"classes", a.classes},
                   {"lambda", a.lambda},
                   {"lr", a.lr},
                   {"seed", a.seed},
                   {"restorer", a.restorer},
                   {"restorer_parameters", config.parameter_count()},
                   {"thetas", thetas}};
  out["repeat"] = a.repeat;
  json stages = json::object();
  for (std::size_t i = 0; i < kStageKeys.size(); ++i) stages[kStageKeys[i]] = ours[i];
  out["vkjr2"] = {{"stages_s", stages},
                  {"step_s", step_s},
                  {"steps_per_s", 1 / step_s},
                  {"landmarks_to_theta_s", landmarks_s},
                  {"landmarks_in_step", false},
                  {"memory",
                   {{"used_bytes", times.peak.used_bytes},
                    {"reserved_bytes", times.peak.reserved_bytes},
                    {"peak_stage", kStageKeys[times.peak_stage]},
                    {"used_bytes_networks_and_inputs", before.used_bytes - before_nets.used_bytes},
                    {"source", "Device::memory_stats() at the end of each stage's recording"}}}};
  if (torch.available) {
    json ratios = json::object();
    for (std::size_t i = 0; i < kStageKeys.size(); ++i) {
      ratios[kStageKeys[i]] = rows[i].ratio_vs_peer();
    }
    out["torch"] = {{"result", torch_result}, {"ratio_stages", ratios}, {"ratio_step", ratio}};
  } else {
    out["torch"] = torch.reason;
  }
  out["goals"] = {{"ratio_vs_torch_on_lavapipe", kTorchGoal}};
  if (lavapipe && torch.available) out["goals"]["torch_met"] = ratio >= kTorchGoal;
  bench::emit_json(out, a.json_path, a.json_out);
}

}  // namespace
}  // namespace vkjr2::cli

namespace {

int run(int argc, char** argv) {
  using namespace vkjr2::cli;
  CLI::App app{"A JR² co-training step, stage by stage, against PyTorch on the CPU",
               "vkjr2 bench cotrain"};
  add_logging_options(app);
  BenchCotrainArgs a;
  app.footer(
      "Times one restore-first co-training step of `vkjr2 cotrain` on the device, stage by stage\n"
      "(student forward, teacher forward, alignment + frozen recognizer + AdaFace head, backward,\n"
      "Adam), on random clips with fixed alignment thetas, and the device memory it holds; then\n"
      "the same graph in PyTorch on the CPU (tools/cotrain_torch.py bench, --threads threads).\n"
      "The landmarks that give the thetas in a real run are timed apart (ours only).\n"
      "Example:\n  vkjr2 bench cotrain --json-file bench_cotrain.json\n"
      "The other benchmarks: vkjr2 bench --help (bench/RESULTS.md has the latest figures).");
  app.add_option("--batch", a.batch, "Clips per step (AdaFace needs 2)")
      ->default_val(a.batch)
      ->check(integer_range(2, 256));
  app.add_option("--window", a.window, "Face window side in pixels (a multiple of 2^levels)")
      ->default_val(a.window)
      ->check(integer_range(16, 512));
  app.add_option("--classes", a.classes, "Identities of the AdaFace head")
      ->default_val(a.classes)
      ->check(integer_range(2, 100000));
  app.add_option("--lambda", a.lambda, "Weight of the self-distillation L1")
      ->default_val(a.lambda)
      ->check(finite_range(0, 1e6));
  app.add_option("--restorer", a.restorer,
                 "The restorer: the teacher and the student's start (default: the shipped one, "
                 "restorer_default.safetensors)");
  app.add_option("--repeat", a.repeat, "Timed steps (medians), after one warm-up")
      ->default_val(a.repeat)
      ->check(integer_range(1, 1000));
  add_seed_option(&app, a.seed, "Seed of the clips, the thetas and the head", a.seed);
  add_torch_peer_options(app, a.peer);
  app.add_option("--device", a.device, "Vulkan device index or name substring (else VKJR2_DEVICE)");
  app.add_option("--json-file", a.json_path, "Also write the results as JSON here");
  app.add_flag("--json", a.json_out, "Print the JSON after the table");
  app.callback([&a] { run_bench_cotrain(a); });
  return run_program(app, argc, argv);
}

}  // namespace

int main(int argc, char** argv) { return vkjr2::cli::program_main(argc, argv, run); }
