// vkjr2 sim-train: make the PSF basis + P2S network the simulator blurs with.
#include <vkjr2/runtime/device.hpp>
#include <vkjr2/runtime/error.hpp>
#include <vkjr2/sim/p2s.hpp>

#include <CLI/CLI.hpp>
#include <nlohmann/json.hpp>

#include <cstdio>
#include <map>
#include <memory>
#include <optional>
#include <string>

#include "checks.hpp"
#include "cleanup.hpp"
#include "commands.hpp"
#include "log.hpp"
#include "media.hpp"
#include "progress.hpp"

namespace vkjr2::cli {
namespace {

// The shipped model's size (artifacts/README.md): 24 kernels of 21×21 hold
// the short-exposure PSFs of the presets (D/r0 ≤ 6) and keep the direct
// PSF-basis convolution at ~10⁴ taps per pixel on lavapipe.
constexpr int kDefaultSize = 21;
constexpr int kDefaultCount = 24;

struct TrainArgs {
  std::string output, preset = "moderate", config, device;
  std::optional<double> wavelength_nm;
  sim::P2sArtifactConfig artifact = [] {
    sim::P2sArtifactConfig c;
    c.basis.size = kDefaultSize;
    c.basis.count = kDefaultCount;
    return c;
  }();
  bool json_out = false, quiet = false, force = false;
};

void run_sim_train(TrainArgs& a) {
  check_output_file(a.output, a.force, "OUT");
  check_extension(a.output, {".safetensors"}, "OUT");
  if (!a.config.empty()) check_input_file(a.config, "--config");
  sim::Params params = a.config.empty() ? sim::preset(a.preset) : sim::load_params(a.config);
  watch_output_folder(std::filesystem::path(a.output).parent_path());
  if (a.wavelength_nm) {
    sim::set_wavelengths(params, {*a.wavelength_nm * 1e-9});
    params.image.channels = 1;
  }
  Device device = open_device(a.device);
  std::map<std::string, std::unique_ptr<Progress>> bars;
  auto progress = [&](const sim::P2sProgress& p) {
    auto& bar = bars[p.stage];
    if (!bar) {
      for (auto& [name, other] : bars)
        if (other) other->done();
      bar = std::make_unique<Progress>("sim-train " + p.stage, std::size_t(p.total), a.quiet);
    }
    bar->update(std::size_t(p.done));
  };
  const sim::P2sTrainReport r =
      sim::make_p2s_artifact(device, params, a.artifact, a.output, progress);
  bars.clear();
  const sim::Derived d = sim::derive(params);
  const auto& b = a.artifact.basis;
  const double wavelength_nm = d.channels[std::size_t(a.artifact.channel)].wavelength_m * 1e9;
  if (a.json_out) {
    const nlohmann::json j = {{"output", a.output},
                              {"channel", a.artifact.channel},
                              {"wavelength_nm", wavelength_nm},
                              {"nyquist", d.channels[std::size_t(a.artifact.channel)].nyquist},
                              {"size", b.size},
                              {"count", b.count},
                              {"psf_samples", b.samples},
                              {"steps", r.steps},
                              {"final_loss", r.final_loss},
                              {"test_p2s_rel_l2", r.test_p2s_rel_l2},
                              {"test_pca_rel_l2", r.test_pca_rel_l2},
                              {"test_mean_psf_rel_l2", r.test_mean_rel_l2},
                              {"train_p2s_rel_l2", r.train_p2s_rel_l2},
                              {"basis_seconds", r.basis_seconds},
                              {"data_seconds", r.data_seconds},
                              {"train_seconds", r.train_seconds},
                              {"total_seconds", r.total_seconds}};
    std::printf("%s\n", j.dump(2).c_str());
  } else {
    std::printf("sim-train: wrote %s (K=%d kernels of %dx%d, λ %.1f nm, Nyquist %.4f) in %.1f s\n",
                a.output.c_str(), b.count, b.size, b.size, wavelength_nm,
                d.channels[std::size_t(a.artifact.channel)].nyquist, r.total_seconds);
    std::printf(
        "  held-out PSF error (relative L2): P2S %.4f, PCA projection %.4f, mean PSF alone %.4f\n",
        r.test_p2s_rel_l2, r.test_pca_rel_l2, r.test_mean_rel_l2);
    std::printf("  %d steps, final loss %.3g; train-set P2S error %.4f\n", r.steps, r.final_loss,
                r.train_p2s_rel_l2);
  }
}

}  // namespace

void add_sim_train(CLI::App& app) {
  auto a = std::make_shared<TrainArgs>();
  CLI::App* cmd = app.add_subcommand(
      "sim-train", "Make the PSF basis and P2S network the simulator blurs with (safetensors)");
  cmd->footer(
      "Draws wave-optics PSFs (pupil × exp(iΣ a_j Z_j) → |FFT|², sampled for the optics' λ, D, f "
      "and pixel pitch),\n"
      "fits their PCA basis, trains the P2S network (Zernike a_4..a_J → basis weights) and reports "
      "the held-out\n"
      "PSF error. Same seeds → same file.\n"
      "Examples:\n"
      "  vkjr2 sim-train artifacts/p2s_default.safetensors --force    # the shipped model\n"
      "  vkjr2 sim-train artifacts/p2s_610nm.safetensors --wavelength 610 --force   # shipped, "
      "red\n"
      "  vkjr2 sim-train mine.safetensors --config optics.json --size 25 --count 24\n"
      "  vkjr2 sim-train blue.safetensors --config rgb.yaml --channel 2   # the config's 3rd "
      "wavelength");
  cmd->add_option("OUT", a->output, "Output .safetensors file")->required();
  cmd->add_option("--preset", a->preset, "Optics and path preset")
      ->default_val("moderate")
      ->check(CLI::IsMember({"weak", "moderate", "strong"}));
  cmd->add_option("--config", a->config,
                  "JSON or YAML parameter file (its optics set the sampling); overrides --preset");
  CLI::Option* wavelength =
      cmd->add_option("--wavelength", a->wavelength_nm,
                      "Train for this wavelength in nm instead of the optics' (same D, f, pitch)")
          ->check(finite_range(100.0, 20000.0));
  cmd->add_option("--channel", a->artifact.channel,
                  "Train for this channel's wavelength of a --config with one per channel")
      ->default_val(0)
      ->check(integer_range(0, 3))
      ->excludes(wavelength);
  auto& b = a->artifact.basis;
  auto& t = a->artifact.train;
  cmd->add_option("--size", b.size, "PSF kernel size S (odd)")
      ->default_val(b.size)
      ->check(odd_number(3, 65));
  cmd->add_option("--count", b.count, "Basis kernels K (the mean PSF + K-1 components)")
      ->default_val(b.count)
      ->check(integer_range(2, 400));
  cmd->add_option("--psf-samples", b.samples, "Wave-optics PSFs for the basis")
      ->default_val(b.samples)
      ->check(integer_range(16, 10000000));
  cmd->add_option("--train-samples", t.train_samples, "PSF/weight pairs for training")
      ->default_val(t.train_samples)
      ->check(integer_range(16, 10000000));
  cmd->add_option("--steps", t.steps, "Training steps")
      ->default_val(t.steps)
      ->check(integer_range(1, 10000000));
  cmd->add_option("--hidden", a->artifact.hidden, "Hidden width of the P2S network")
      ->default_val(a->artifact.hidden)
      ->check(integer_range(1, 4096));
  add_seed_option(cmd, t.seed, "Seed of the training draws (the basis uses --basis-seed)", t.seed);
  add_seed_option(cmd, b.seed, "Seed of the basis PSFs", b.seed, "--basis-seed");
  cmd->add_option("--residual-modes", b.residual_j_max,
                  "The PSFs also carry Noll modes J+1..this (not network inputs), so the model "
                  "predicts the mean PSF given a_4..a_J, residual blur included; <= J: none")
      ->default_val(b.residual_j_max)
      ->check(integer_range(4, sim::kMaxZernikeModes));
  cmd->add_option("--device", a->device,
                  "Vulkan device index or name substring (else VKJR2_DEVICE)");
  cmd->add_flag("--json", a->json_out, "Print JSON instead of text");
  cmd->add_flag("--quiet", a->quiet, "No progress bar");
  cmd->add_flag("--force", a->force, "Replace an existing output file");
  cmd->callback([a] {
    a->artifact.train.residual_j_max = a->artifact.basis.residual_j_max;
    run_sim_train(*a);
  });
}

}  // namespace vkjr2::cli
