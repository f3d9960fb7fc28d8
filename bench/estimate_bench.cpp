// vkjr2 bench estimate (this program, estimate_bench, run by `vkjr2 bench
// estimate`): the two registrations of the turbulence estimate
// (jr2/turbulence.hpp) on the same simulated videos: vkjr2's Lucas–Kanade
// kernel on the device against OpenCV's DIS optical flow (what `vkjr2
// estimate` uses), in time and in how well each finds the simulator's own
// tilt; and the spread of the raw D/r0 from DIS against the spread that even
// the simulator's exact tilt maps give over one video, the floor of any
// estimate from that much footage.
#include <vkjr2/jr2/benchmark.hpp>
#include <vkjr2/jr2/turbulence.hpp>
#include <vkjr2/runtime/device.hpp>
#include <vkjr2/runtime/stream.hpp>
#include <vkjr2/sim/p2s_blur_model.hpp>
#include <vkjr2/sim/simulator.hpp>

#include <CLI/CLI.hpp>
#include <nlohmann/json.hpp>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <string>
#include <vector>

#include "cli/checks.hpp"
#include "cli/log.hpp"
#include "cli/progress.hpp"
#include "cli/registration.hpp"
#include "cli/run.hpp"
#include "harness.hpp"

namespace vkjr2::cli {
namespace {

struct BenchEstimateArgs {
  std::string device, json_path;
  jr2::TiltOptions tilt;
  std::vector<double> strengths{1.5, 3.0, 6.0};
  int videos = 8, frames = 30, size = 160;
  bool json_out = false, quiet = false;
};

// A scene with detail at several scales and a few flat patches, 0..1.
std::vector<float> scene(int size) {
  std::vector<float> v(3 * std::size_t(size) * std::size_t(size));
  for (int c = 0; c < 3; ++c) {
    for (int y = 0; y < size; ++y) {
      for (int x = 0; x < size; ++x) {
        const double flat = (x / 40 + y / 40) % 3 == 0 ? 0.2 : 1.0;
        v[(std::size_t(c) * size + y) * size + x] =
            float(0.5 + flat * (0.15 * std::sin(0.35 * x + 0.1 * y) +
                                0.12 * std::cos(0.29 * y - 0.07 * x + c) +
                                0.08 * std::sin(0.8 * x) * std::cos(0.7 * y)));
      }
    }
  }
  return v;
}

// One-axis temporal variance of flows [T, 2, H, W] (planar) over every
// pixel `border` or more from the edge.
double tilt_variance(const std::vector<float>& flow, int t, int size, int border) {
  jr2::TiltOptions every;
  every.border = border;
  const std::vector<float> textured(std::size_t(size) * std::size_t(size), 1.f);
  return jr2::tilt_statistics(flow, t, size, size, textured, every).variance_px2;
}

double median(std::vector<double> v) {
  std::sort(v.begin(), v.end());
  const std::size_t n = v.size();
  return n % 2 ? v[n / 2] : 0.5 * (v[n / 2 - 1] + v[n / 2]);
}

double log_sd(const std::vector<double>& ratios) {
  double m = 0, m2 = 0;
  for (double r : ratios) {
    m += std::log(r);
    m2 += std::log(r) * std::log(r);
  }
  m /= double(ratios.size());
  return std::sqrt(std::max(m2 / double(ratios.size()) - m * m, 0.0));
}

void run_bench_estimate(const BenchEstimateArgs& a) {
  if (!a.json_path.empty()) check_output_file(a.json_path, true, "--json-file");
  const Device device = open_device(a.device);
  const auto blur = sim::load_shipped_blur_models(device);
  const int t = a.frames, s = a.size;
  const Tensor x = Tensor::from(device, {1, 3, s, s}, scene(s));
  const jr2::TiltOptions& options = a.tilt;
  double ours_seconds = 0, dis_seconds = 0;
  std::vector<double> ours_err, dis_err;       // |measured / exact − 1| of the tilt variance
  std::vector<double> exact_ratio, dis_ratio;  // raw D/r0 / true D/r0
  nlohmann::json per = nlohmann::json::array();
  Progress bar("bench estimate", a.strengths.size() * std::size_t(a.videos), a.quiet);
  for (double d : a.strengths) {
    const sim::Params params = jr2::probe_sim_params(d, s);
    for (int v = 0; v < a.videos; ++v) {
      const jr2::SimulatedVideo video = jr2::simulate_video(
          device, x, params, jr2::probe_sim_options(), blur, 1000 + std::uint64_t(v), t);
      const std::vector<float>& grey = video.grey;
      const std::vector<float>& flows = video.flow;
      Stream stream(device);
      const double exact = tilt_variance(flows, t, s, options.border);
      // Ours, on the device (upload included).
      jr2::TiltMeasure ours;
      ours_seconds += bench::seconds_of([&] {
        ours = jr2::measure_tilt(stream, Tensor::from(device, {t, 1, s, s}, grey), options);
      });
      // OpenCV DIS: every frame against the 8-bit mean, as ours registers.
      std::vector<float> dis_flow;
      dis_seconds += bench::seconds_of([&] { dis_flow = dis_register(grey, t, s, s).flow; });
      const double dis_var = tilt_variance(dis_flow, t, s, options.border);
      ours_err.push_back(std::abs(ours.variance_px2 / exact - 1));
      dis_err.push_back(std::abs(dis_var / exact - 1));
      const double raw_exact = jr2::raw_d_over_r0(exact, t, params, 0.9);
      const double raw_dis = jr2::raw_d_over_r0(dis_var, t, params, 0.9);
      exact_ratio.push_back(raw_exact / d);
      dis_ratio.push_back(raw_dis / d);
      per.push_back({{"d_over_r0", d},
                     {"seed", 1000 + v},
                     {"exact_variance_px2", exact},
                     {"vkjr2_variance_px2", ours.variance_px2},
                     {"dis_variance_px2", dis_var},
                     {"raw_d_over_r0_exact", raw_exact},
                     {"raw_d_over_r0_dis", raw_dis}});
      bar.update(per.size());
    }
  }
  bar.done();
  const double n = double(per.size());
  const std::string dis_name = "OpenCV DIS (medium, " + std::to_string(dis_threads()) + " threads)";
  std::vector<bench::Result> rows;
  rows.push_back(
      {"lk registration, one video (" + std::to_string(t) + "×" + std::to_string(s) + "²)",
       ours_seconds / n, "s", dis_name, dis_seconds / n, -1, false});
  rows.push_back({"lk tilt variance, median |error| vs exact", median(ours_err), "fraction",
                  dis_name, median(dis_err), -1, false});
  rows.push_back({"DIS raw D/r0 spread over videos (sd of log)", log_sd(dis_ratio), "log",
                  "the simulator's exact tilt maps", log_sd(exact_ratio), -1, false});
  bench::print_table("vkjr2 bench estimate — the tilt registrations of vkjr2 estimate", device,
                     rows);
  std::printf("\n%d videos per D/r0 in {", a.videos);
  for (std::size_t i = 0; i < a.strengths.size(); ++i) {
    std::printf("%s%.2g", i ? ", " : "", a.strengths[i]);
  }
  std::printf(
      "} of %d frames, %d² RGB, the benchmark probes' simulator settings (tilt correlation 0.9);\n"
      "lk: vkjr2's Lucas–Kanade kernel on the device (estimate-train --registration lk); DIS:\n"
      "OpenCV's, what vkjr2 estimate uses. The exact tilt maps are the simulator's own; their\n"
      "spread is what any estimate from one such video inherits: a floor, not a flaw of the\n"
      "registration.\n",
      t, s);
  nlohmann::json out = bench::to_json(device, rows);
  out["videos"] = per;
  bench::emit_json(out, a.json_path, a.json_out);
}

}  // namespace
}  // namespace vkjr2::cli

namespace {

int run(int argc, char** argv) {
  using namespace vkjr2::cli;
  CLI::App app{"The turbulence estimate's tilt registration against OpenCV DIS optical flow",
               "vkjr2 bench estimate"};
  add_logging_options(app);
  BenchEstimateArgs a;
  app.footer(
      "Example:\n  vkjr2 bench estimate --json-file bench_estimate.json\n"
      "The other benchmarks: vkjr2 bench --help (bench/RESULTS.md has the latest figures).");
  app.add_option("--strengths", a.strengths, "True D/r0 of the simulated videos")
      ->default_val(std::vector<double>{1.5, 3.0, 6.0})
      ->check(finite_range(0.5, 20.0));
  app.add_option("--videos", a.videos, "Videos per strength (simulator seeds)")
      ->default_val(8)
      ->check(integer_range(2, 1000));
  app.add_option("--frames", a.frames, "Frames per video")
      ->default_val(30)
      ->check(integer_range(2, 1000));
  app.add_option("--size", a.size, "Square frame size")
      ->default_val(160)
      ->check(integer_range(32, 1024));
  app.add_option("--radius", a.tilt.radius, "Registration window radius (px)")
      ->default_val(a.tilt.radius)
      ->check(integer_range(1, 32));
  app.add_option("--iterations", a.tilt.iterations, "Lucas–Kanade steps per pass")
      ->default_val(a.tilt.iterations)
      ->check(integer_range(1, 100));
  app.add_option("--passes", a.tilt.passes, "Registration passes")
      ->default_val(a.tilt.passes)
      ->check(integer_range(1, 10));
  app.add_option("--device", a.device, "Vulkan device index or name substring (else VKJR2_DEVICE)");
  app.add_option("--json-file", a.json_path, "Also write the results as JSON here");
  app.add_flag("--json", a.json_out, "Print the JSON after the table");
  app.add_flag("--quiet", a.quiet, "No progress bar");
  app.callback([&a] {
    a.tilt.validate();
    run_bench_estimate(a);
  });
  return run_program(app, argc, argv);
}

}  // namespace

int main(int argc, char** argv) { return vkjr2::cli::program_main(argc, argv, run); }
