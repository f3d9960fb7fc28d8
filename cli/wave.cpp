// vkjr2 wave: image a scene through the wave-optics reference.
#include <vkjr2/runtime/device.hpp>
#include <vkjr2/runtime/error.hpp>
#include <vkjr2/runtime/image.hpp>
#include <vkjr2/sim/wave_image.hpp>

#include <CLI/CLI.hpp>
#include <nlohmann/json.hpp>

#include <chrono>
#include <cstdio>
#include <memory>
#include <string>

#include "checks.hpp"
#include "cleanup.hpp"
#include "commands.hpp"
#include "log.hpp"
#include "media.hpp"
#include "progress.hpp"
#include "sim_common.hpp"

namespace vkjr2::cli {
namespace {

struct WaveArgs {
  PathArgs path;
  std::string input, output, device, fft = "device";
  sim::WaveImageConfig config;
  bool json_out = false, quiet = false, force = false;
};

void run_wave(WaveArgs& a) {
  const std::filesystem::path in(a.input), out(a.output);
  check_input_file(in, "IN");
  if (!is_image_path(in)) {
    throw UsageError("IN", a.input + " is not an image (by its extension)",
                     "the wave-optics reference images single frames: pass .png/.jpg/.tif/.npy");
  }
  check_output_file(out, a.force, "OUT");
  check_extension(out, kImageOutputExtensions, "OUT");
  (void)params_for_image(a.path, 64, 64);  // the options, before the image is read
  const Image img = read_image(in);
  const sim::Params p = params_for_image(a.path, int(img.shape[0]), int(img.shape[1]));
  watch_output_folder(out.parent_path());
  a.config.wave.fft = a.fft == "fftw" ? sim::FftBackend::fftw : sim::FftBackend::device;
  const Device device = open_device(a.device);
  sim::WaveImageReport rep;
  Progress bar("wave: source rows", 0, a.quiet);
  const auto t0 = std::chrono::steady_clock::now();
  const auto y = sim::wave_image(device, p, a.config, image_to_planes(img, p.image.channels, 255.f),
                                 &rep, [&](int done, int) { bar.update(std::size_t(done)); });
  bar.done();
  const double seconds =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  write_image(out, planes_to_image(y, p.image.channels, img.shape[0], img.shape[1], 3, 255.f),
              a.force);
  const sim::WavePlan& plan = rep.plans.front();
  for (const auto& w : plan.warnings) log_warn(w);
  if (a.json_out) {
    const nlohmann::json j = {{"input", a.input},
                              {"output", a.output},
                              {"seconds", seconds},
                              {"psf_seconds", rep.psf_seconds},
                              {"image_seconds", rep.image_seconds},
                              {"sources", {rep.sources_y, rep.sources_x}},
                              {"psf_size", rep.psf_size},
                              {"fft", sim::fft_backend_name(a.config.wave.fft)},
                              {"grid", plan.grid},
                              {"screens", plan.z_m.size()},
                              {"spacing_m", plan.spacing_m},
                              {"pupil_fft", plan.pupil_fft},
                              {"r0_m", plan.r0_spherical_m},
                              {"warnings", plan.warnings}};
    std::printf("%s\n", j.dump(2).c_str());
  } else {
    std::printf("wave: %s -> %s in %.1f s (PSFs %.1f s, imaging %.1f s)\n", a.input.c_str(),
                a.output.c_str(), seconds, rep.psf_seconds, rep.image_seconds);
    std::printf(
        "  %dx%d point sources, %d screens on a %d² grid (δ = %.2f mm), PSFs %dx%d, r0 = %.2f cm\n",
        rep.sources_x, rep.sources_y, int(plan.z_m.size()), plan.grid, plan.spacing_m * 1e3,
        rep.psf_size, rep.psf_size, plan.r0_spherical_m * 100);
  }
}

}  // namespace

void add_wave(CLI::App& app) {
  auto a = std::make_shared<WaveArgs>();
  CLI::App* cmd =
      app.add_subcommand("wave", "Image a scene through the split-step wave-optics reference");
  cmd->footer(
      "Point sources on a grid over the field are propagated through shared phase screens (Hardie "
      "et al. 2017);\n"
      "each pixel is imaged with the PSF interpolated between its four nearest sources, tilt "
      "included.\n"
      "Slow by design: it is the ground truth the fast simulator is checked and timed against.\n"
      "Examples:\n"
      "  vkjr2 wave face.png face_wave.png --preset strong --source-step 8\n"
      "  vkjr2 wave face.png out.png --grid 128 --screens 5 --json\n"
      "  vkjr2 wave face.png out.png --fft fftw");
  cmd->add_option("IN", a->input, "Input image (.png, .jpg, .tif, .npy)")->required();
  cmd->add_option("OUT", a->output, "Output image (.png, .jpg, .tif, .bmp: by its extension)")
      ->required();
  add_path_options(cmd, a->path);
  add_seed_option(cmd, a->config.wave.seed, "Seed of the phase screens");
  cmd->add_option("--grid", a->config.wave.grid,
                  "Propagation grid N (an FFT length: 2^a 3^b 5^c 7^d)")
      ->default_val(256)
      ->check(fft_length(16, 4096));
  cmd->add_option("--screens", a->config.wave.screens,
                  "Phase screens (at least; more if a slab's Rytov is high)")
      ->default_val(10)
      ->check(integer_range(1, 200));
  cmd->add_option("--source-step", a->config.source_step_px, "Point-source spacing in pixels")
      ->default_val(16)
      ->check(finite_range(1.0, 4096.0));
  cmd->add_option("--psf-size", a->config.psf_size, "PSF size in pixels (odd; 0 = from the seeing)")
      ->default_val(0)
      ->check(odd_number(3, 65, true));
  cmd->add_option("--fft", a->fft,
                  "Where the FFTs run: device (with the rest of the reference) or fftw (all on "
                  "the CPU)")
      ->default_val("device")
      ->check(CLI::IsMember({"device", "fftw"}));
  cmd->add_option("--device", a->device,
                  "Vulkan device index or name substring (else VKJR2_DEVICE)");
  cmd->add_flag("--json", a->json_out, "Print JSON instead of text");
  cmd->add_flag("--quiet", a->quiet, "No progress bar");
  cmd->add_flag("--force", a->force, "Replace an existing output file");
  cmd->callback([a] { run_wave(*a); });
}

}  // namespace vkjr2::cli
