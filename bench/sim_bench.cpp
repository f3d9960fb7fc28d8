// vkjr2 bench sim (this program, sim_bench, run by `vkjr2 bench sim`): the
// fast simulator's frame rate and its speedup over the wave-optics reference
// on the same parameters, measured twice in the same run: on the same
// device, and with its FFTs on FFTW on the CPU (the fastest wave optics a
// user of this machine could run).
#include <vkjr2/runtime/device.hpp>
#include <vkjr2/runtime/image.hpp>
#include <vkjr2/runtime/stream.hpp>
#include <vkjr2/sim/p2s_blur_model.hpp>
#include <vkjr2/sim/simulator.hpp>
#include <vkjr2/sim/wave_image.hpp>

#include <CLI/CLI.hpp>
#include <nlohmann/json.hpp>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <iterator>
#include <string>
#include <vector>

#include "cli/checks.hpp"
#include "cli/log.hpp"
#include "cli/media.hpp"
#include "cli/run.hpp"
#include "harness.hpp"

namespace vkjr2::cli {
namespace {

struct BenchSimArgs {
  std::string preset = "moderate", device, json_path;
  std::vector<int> sizes{256, 512, 1024};
  int frames = 3;
  double wave_step_px = 16;
  int wave_grid = 256;
  bool json_out = false;
};

// A folder of this process's own under the system's temporary one, removed
// with everything in it.
struct ScratchDir {
  std::filesystem::path path =
      std::filesystem::temp_directory_path() / ("vkjr2-bench-sim-" + std::to_string(::getpid()));
  ScratchDir() { std::filesystem::create_directories(path); }
  ~ScratchDir() {
    std::error_code ec;
    std::filesystem::remove_all(path, ec);
  }
  ScratchDir(const ScratchDir&) = delete;
  ScratchDir& operator=(const ScratchDir&) = delete;
};

struct StageRow {
  std::string tag;
  double fields, warp, p2s, blur, noise, io, sum, frame;
};

std::vector<float> test_scene(int channels, int h, int w) {
  std::vector<float> v(std::size_t(channels) * std::size_t(h) * std::size_t(w));
  std::size_t i = 0;
  for (int c = 0; c < channels; ++c)
    for (int y = 0; y < h; ++y)
      for (int x = 0; x < w; ++x) v[i++] = 0.5f + 0.4f * float(((x / 7 + y / 7 + c) % 2)) - 0.2f;
  return v;
}

// What `vkjr2 simulate in.png out.png` adds to a frame: the PNG read, its
// upload as planes, the result's download and the PNG write (seconds, the
// median of `frames`), on the frame y holds.
double io_seconds(const Device& device, const Tensor& y, const std::filesystem::path& dir,
                  int frames) {
  const std::filesystem::path png = dir / "frame.png";
  const int channels = int(y.shape()[1]);
  // A device frame as the 8-bit RGB image the CLI writes.
  const auto to_image = [&](const Tensor& t) {
    return planes_to_image(image_to_planes(image_to_host(t)), channels, y.shape()[2], y.shape()[3],
                           3, 255.f);
  };
  write_image(png, to_image(y), true);
  return bench::median_seconds(
      [&] {
        const Tensor x = image_to_device(device, read_image(png), channels, 255.f);
        write_image(png, to_image(x), true);
      },
      frames, 0);
}

void run_bench_sim(const BenchSimArgs& a) {
  // Benchmark results are replaced; the folder must be there before minutes of work.
  if (!a.json_path.empty()) check_output_file(a.json_path, true, "--json-file");
  const Device device = open_device(a.device);
  const auto blur = sim::load_shipped_blur_models(device);
  std::vector<bench::Result> rows;
  std::vector<StageRow> stage_rows;
  const ScratchDir scratch;
  nlohmann::json per_size = nlohmann::json::array();

  // The reference on one 256² grey frame with sources every wave_step_px.
  sim::Params wp = sim::preset(a.preset);
  wp.image = {256, 256, 1, 1};
  sim::WaveImageConfig wc;
  wc.source_step_px = a.wave_step_px;
  wc.wave.grid = a.wave_grid;
  sim::WaveImageReport wr;
  std::fprintf(stderr, "bench sim: wave-optics reference, 256² grey, sources every %.0f px ...\n",
               a.wave_step_px);
  const double wave_seconds = bench::median_seconds(
      [&] { sim::wave_image(device, wp, wc, test_scene(1, 256, 256), &wr); }, 1, 0);
  const int wave_sources = wr.sources_x * wr.sources_y;
  const double per_source = wr.psf_seconds / wave_sources;
  const double imaging_per_px = wr.image_seconds / (256.0 * 256.0);
  const sim::WavePlan& plan = wr.plans.front();
  // The same run with its FFTs on FFTW (one thread) and nothing on the
  // device; the first row of sources includes FFTW's planning (MEASURE).
  sim::WaveImageConfig wc_fftw = wc;
  wc_fftw.wave.fft = sim::FftBackend::fftw;
  sim::WaveImageReport wr_fftw;
  std::fprintf(stderr, "bench sim: the same with its FFTs on FFTW (CPU, 1 thread) ...\n");
  const double fftw_seconds = bench::median_seconds(
      [&] { sim::wave_image(device, wp, wc_fftw, test_scene(1, 256, 256), &wr_fftw); }, 1, 0);
  const double per_source_fftw = wr_fftw.psf_seconds / wave_sources;
  const double imaging_per_px_fftw = wr_fftw.image_seconds / (256.0 * 256.0);

  for (int size : a.sizes) {
    // Grey; RGB at one wavelength; RGB at one wavelength per channel
    // (sim::kRgbWavelengthsM: a blur model and a PSF-convolution pass each).
    for (const int wavelengths : {0, 1, 3}) {
      const int channels = wavelengths == 0 ? 1 : 3;
      sim::Params p = sim::preset(a.preset);
      p.image = {size, size, channels, 1};
      if (wavelengths == 3)
        p.optics.wavelengths_m.assign(std::begin(sim::kRgbWavelengthsM),
                                      std::end(sim::kRgbWavelengthsM));
      sim::Simulator s(device, p, blur, {});
      Tensor x = Tensor::from(device, {1, channels, size, size}, test_scene(channels, size, size));
      Tensor y = Tensor::empty(device, x.shape());
      Stream stream(device);
      s.reset(1);
      const double sec = bench::median_seconds(
          [&] {
            s.frame(stream, x, y);
            stream.run();
          },
          a.frames, 1);
      // Where the time goes: the same frames stage by stage (each stage's
      // stream run apart), their mean, and the image I/O of the CLI.
      sim::FrameStages st;
      for (int i = 0; i < a.frames; ++i) s.frame(stream, x, y, st);
      const double io = io_seconds(device, y, scratch.path, a.frames);
      // The reference at the fast simulator's PSF-field resolution: one
      // propagation per grid point (its cost is linear in sources; measured
      // per source above), plus the pixel sum (linear in pixels and channels).
      const double matched_sources = double(s.field().grid_h()) * s.field().grid_w();
      // One wavelength: the PSFs serve every channel; the sum runs per
      // channel. One per channel: the reference propagates each wavelength
      // (the phase scales as 1/λ, diffraction as λ) on the same grid.
      const double psf_sets = wavelengths == 3 ? 3.0 : 1.0;
      const double wave_matched =
          per_source * matched_sources * psf_sets + imaging_per_px * double(size) * size * channels;
      const double fftw_matched = per_source_fftw * matched_sources * psf_sets +
                                  imaging_per_px_fftw * double(size) * size * channels;
      const std::string tag = std::to_string(size) + "² " +
                              (wavelengths == 0   ? "grey"
                               : wavelengths == 1 ? "colour"
                                                  : "colour 3λ");
      rows.push_back({"sim " + a.preset + " " + tag, 1 / sec, "frames/s",
                      "wave ref., matched grid (extrap.)", 1 / wave_matched});
      rows.push_back({"sim " + a.preset + " " + tag, 1 / sec, "frames/s",
                      "wave ref. FFTW, matched (extrap.)", 1 / fftw_matched});
      nlohmann::json j = {{"size", size},
                          {"channels", channels},
                          {"wavelengths", std::max(1, wavelengths)},
                          {"fps", 1 / sec},
                          {"seconds_per_frame", sec},
                          {"field_grid", {s.field().grid_h(), s.field().grid_w()}},
                          {"field_step_px", s.field().step_x_px()},
                          {"wave_seconds_matched_grid", wave_matched},
                          {"wave_fftw_seconds_matched_grid", fftw_matched},
                          {"wave_matched_is_extrapolated", true},
                          {"speedup_vs_wave_same_device", wave_matched / sec},
                          {"speedup_vs_wave_fftw", fftw_matched / sec}};
      if (size == 256 && channels == 1) {
        j["wave_seconds_measured"] = wave_seconds;
        j["speedup_vs_wave_measured_grid"] = wave_seconds / sec;
        j["wave_fftw_seconds_measured"] = fftw_seconds;
        j["speedup_vs_wave_fftw_measured_grid"] = fftw_seconds / sec;
        const std::string sources = std::to_string(wr.sources_x) + "² sources (meas.)";
        rows.push_back({"sim " + a.preset + " " + tag, 1 / sec, "frames/s", "wave ref., " + sources,
                        1 / wave_seconds});
        rows.push_back({"sim " + a.preset + " " + tag, 1 / sec, "frames/s",
                        "wave ref. FFTW, " + sources, 1 / fftw_seconds});
      }
      const double n = a.frames;
      j["stages_seconds"] = {{"fields", st.fields / n}, {"warp", st.warp / n},
                             {"p2s", st.p2s / n},       {"blur", st.blur / n},
                             {"noise", st.noise / n},   {"image_io", io}};
      stage_rows.push_back({tag, st.fields / n, st.warp / n, st.p2s / n, st.blur / n, st.noise / n,
                            io, st.total() / n, sec});
      per_size.push_back(j);
      std::fprintf(stderr, "bench sim: %s %.3f s/frame\n", tag.c_str(), sec);
    }
  }
  bench::print_table(
      "vkjr2 bench sim — fast simulator vs the wave-optics reference (" + a.preset + ")", device,
      rows);
  std::printf(
      "\nwhere a frame's time goes (ms, mean of %d frames run stage by stage; image I/O: PNG "
      "read + upload + download + PNG write, as vkjr2 simulate does; not in the frame)\n",
      a.frames);
  std::printf("%-18s %9s %9s %9s %9s %9s %9s %11s %11s\n", "frame", "fields", "warp", "P2S", "blur",
              "noise", "image I/O", "sum stages", "pipelined");
  for (const StageRow& r : stage_rows) {
    std::printf("%-18s %9.1f %9.1f %9.1f %9.1f %9.1f %9.1f %11.1f %11.1f\n", r.tag.c_str(),
                1e3 * r.fields, 1e3 * r.warp, 1e3 * r.p2s, 1e3 * r.blur, 1e3 * r.noise, 1e3 * r.io,
                1e3 * r.sum, 1e3 * r.frame);
  }
  std::printf("(pipelined: the frame as the timed rows above run it, one stream run a frame)\n");
  std::printf(
      "\nwave-optics reference: %d² propagation grid, %zu screens, δ = %.2f mm, pupil FFT %d, PSFs "
      "%dx%d;\n"
      "measured on 256² grey with %dx%d sources every %.0f px: %.1f s (%.3f s per source, %.2f s "
      "imaging).\n"
      "the same with its FFTs on FFTW on the CPU (1 thread, FFTW_MEASURE plans; screens, "
      "propagation and\n"
      "PSFs all on the host, nothing on the device): %.1f s (%.3f s per source, %.2f s imaging).\n"
      "Matched grid: one source per fast-simulator field point (the same PSF-field resolution), "
      "extrapolated\n"
      "from the measured per-source cost of each (speedup_vs_wave_same_device, "
      "speedup_vs_wave_fftw).\n",
      plan.grid, plan.z_m.size(), plan.spacing_m * 1e3, plan.pupil_fft, wr.psf_size, wr.psf_size,
      wr.sources_x, wr.sources_y, a.wave_step_px, wave_seconds, per_source, wr.image_seconds,
      fftw_seconds, per_source_fftw, wr_fftw.image_seconds);
  nlohmann::json out = bench::to_json(device, rows);
  out["sizes"] = per_size;
  out["wave_reference"] = {{"grid", plan.grid},
                           {"screens", plan.z_m.size()},
                           {"spacing_m", plan.spacing_m},
                           {"pupil_fft", plan.pupil_fft},
                           {"psf_size", wr.psf_size},
                           {"sources", {wr.sources_y, wr.sources_x}},
                           {"seconds", wave_seconds},
                           {"seconds_per_source", per_source},
                           {"fftw_seconds", fftw_seconds},
                           {"fftw_seconds_per_source", per_source_fftw},
                           {"fftw_threads", 1}};
  bench::emit_json(out, a.json_path, a.json_out);
}

}  // namespace
}  // namespace vkjr2::cli

namespace {

int run(int argc, char** argv) {
  using namespace vkjr2::cli;
  CLI::App app{
      "Fast simulator frames/s and speedup over the wave-optics reference (device and FFTW CPU)",
      "vkjr2 bench sim"};
  add_logging_options(app);
  BenchSimArgs a;
  app.footer(
      "Example:\n  vkjr2 bench sim --json-file bench_sim.json\n"
      "The other benchmarks: vkjr2 bench --help (bench/RESULTS.md has the latest figures).");
  app.add_option("--preset", a.preset, "Turbulence preset")
      ->default_val("moderate")
      ->check(CLI::IsMember({"weak", "moderate", "strong"}));
  app.add_option("--sizes", a.sizes, "Square frame sizes")
      ->default_val(std::vector<int>{256, 512, 1024})
      ->check(integer_range(16, 2048));
  app.add_option("--frames", a.frames, "Timed frames per size (median)")
      ->default_val(3)
      ->check(integer_range(1, 1000));
  app.add_option("--wave-step", a.wave_step_px,
                 "Source spacing of the measured wave-optics run (px)")
      ->default_val(16)
      ->check(finite_range(2.0, 256.0));
  app.add_option("--wave-grid", a.wave_grid, "Wave-optics propagation grid")
      ->default_val(256)
      ->check(fft_length(64, 4096));
  app.add_option("--device", a.device, "Vulkan device index or name substring (else VKJR2_DEVICE)");
  app.add_option("--json-file", a.json_path, "Also write the results as JSON here");
  app.add_flag("--json", a.json_out, "Print the JSON after the table");
  app.callback([&a] { run_bench_sim(a); });
  return run_program(app, argc, argv);
}

}  // namespace

int main(int argc, char** argv) { return vkjr2::cli::program_main(argc, argv, run); }
