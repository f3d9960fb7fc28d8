// vkjr2 sim-validate: the simulator's physics checks at full size, as a table.
#include <vkjr2/runtime/device.hpp>
#include <vkjr2/sim/p2s_blur_model.hpp>
#include <vkjr2/sim/validate.hpp>

#include <CLI/CLI.hpp>
#include <nlohmann/json.hpp>

#include <chrono>
#include <cstdio>
#include <memory>
#include <string>
#include <vector>

#include "checks.hpp"
#include "commands.hpp"
#include "log.hpp"
#include "progress.hpp"
#include "sim_common.hpp"

namespace vkjr2::cli {
namespace {

struct ValidateArgs {
  std::string preset = "moderate", device, also_at = "610,465";
  sim::ValidationConfig config;
  bool quick = false, json_out = false, quiet = false, no_psf = false;
};

// Exit code 1 when a check fails (after printing the whole table).
void run_sim_validate(ValidateArgs& a) {
  if (a.quick) {
    a.config.fields = 100;
    a.config.screens = 16;
    a.config.psf_frames = 16;
  }
  if (!a.no_psf && !a.also_at.empty() && a.also_at != "none")
    a.config.extra_wavelengths_m = parse_wavelengths_nm(a.also_at, "--also-at");
  const Device device = open_device(a.device);
  std::vector<std::shared_ptr<const sim::BlurModel>> blur;
  if (!a.no_psf) blur = sim::load_shipped_blur_models(device);
  Progress bar("sim-validate", a.no_psf ? std::size_t(2) : 3 + a.config.extra_wavelengths_m.size(),
               a.quiet);
  const auto t0 = std::chrono::steady_clock::now();
  const auto rows = sim::validate_simulator(device, a.preset, a.config, blur,
                                            [&](int done, int) { bar.update(std::size_t(done)); });
  bar.done();
  const double seconds =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  int failed = 0;
  for (const auto& r : rows) failed += r.pass() ? 0 : 1;
  if (a.json_out) {
    nlohmann::json j = {{"preset", a.preset},
                        {"seconds", seconds},
                        {"failed", failed},
                        {"checks", nlohmann::json::array()}};
    for (const auto& r : rows) {
      j["checks"].push_back({{"check", r.check},
                             {"measured", r.measured},
                             {"sigma", r.sigma},
                             {"expected", r.expected},
                             {"tolerance", r.tolerance},
                             {"pass", r.pass()},
                             {"note", r.note}});
    }
    std::printf("%s\n", j.dump(2).c_str());
  } else {
    std::printf("sim-validate (%s preset; %d fields, %d screens, %d PSF frames) in %.1f s\n",
                a.preset.c_str(), a.config.fields, a.config.screens, a.config.psf_frames, seconds);
    std::printf("%-46s %12s %10s %12s %10s  %s\n", "check", "measured", "sigma", "expected",
                "tolerance", "result");
    for (const auto& r : rows) {
      std::printf("%-46s %12.5g %10.3g %12.5g %10.3g  %s  %s\n", r.check.c_str(), r.measured,
                  r.sigma, r.expected, r.tolerance, r.pass() ? "PASS" : "FAIL", r.note.c_str());
    }
    std::printf("%zu passed, %d failed\n", rows.size() - std::size_t(failed), failed);
  }
  if (failed > 0)
    throw Error("sim-validate", std::to_string(failed) + " check(s) failed", "see the table above");
}

}  // namespace

void add_sim_validate(CLI::App& app) {
  auto a = std::make_shared<ValidateArgs>();
  CLI::App* cmd = app.add_subcommand(
      "sim-validate", "Run the simulator's physics checks at full size (pass/fail table)");
  cmd->footer(
      "Checks: Noll covariance and tilt variance of the sampled fields, tilt correlation vs "
      "separation against the\n"
      "path-integrated theory, AR(1) frame correlation, the phase screens' structure function; "
      "point sources through\n"
      "both simulators: long-exposure PSF (fast vs wave optics), long- and short-exposure MTF "
      "vs Fried's\n"
      "exp{-3.44 (r/r0)^(5/3) [1 - alpha (r/D)^(1/3)]}, and the wave optics' G-tilt variance vs "
      "theory and vs the\n"
      "fast simulator; the PSF checks again at 610 and 465 nm (--also-at), the RGB channels' "
      "wavelengths.\nEach bound is 4 sigma of its estimator\n"
      "unless the row says otherwise. Exit code 1 when a check fails.\n"
      "Examples:\n  vkjr2 sim-validate\n  vkjr2 sim-validate --preset strong --json");
  cmd->add_option("--preset", a->preset, "Turbulence preset")
      ->default_val("moderate")
      ->check(CLI::IsMember({"weak", "moderate", "strong"}));
  cmd->add_option("--fields", a->config.fields, "Independent 96x128 fields")
      ->default_val(600)
      ->check(integer_range(10, 1000000));
  cmd->add_option("--screens", a->config.screens, "Phase screens (128²)")
      ->default_val(64)
      ->check(integer_range(2, 100000));
  cmd->add_option("--psf-frames", a->config.psf_frames, "Point-source realizations per simulator")
      ->default_val(96)
      ->check(integer_range(2, 100000));
  add_seed_option(cmd, a->config.seed, "Seed", 2026);
  cmd->add_option("--wave-screen", a->config.wave_screen_size,
                  "Side of the wave reference's phase screens (an FFT length >= its grid, 128)")
      ->default_val(a->config.wave_screen_size)
      ->check(integer_range(128, 4096));
  cmd->add_flag("--quick", a->quick, "Small sizes (as in the test suite)");
  cmd->add_flag("--no-psf", a->no_psf, "Skip the fast-vs-wave PSF comparison");
  cmd->add_option("--also-at", a->also_at,
                  "Repeat the PSF checks at these wavelengths in nm (the RGB channels' blur "
                  "models; 'none' to skip)")
      ->default_val("610,465");
  cmd->add_option("--device", a->device,
                  "Vulkan device index or name substring (else VKJR2_DEVICE)");
  cmd->add_flag("--json", a->json_out, "Print JSON instead of text");
  cmd->add_flag("--quiet", a->quiet, "No progress bar");
  cmd->callback([a] { run_sim_validate(*a); });
}

}  // namespace vkjr2::cli
