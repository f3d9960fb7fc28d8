// vkjr2 wave-clips: a cached test set of clips degraded by the wave-optics
// reference; vkjr2 restore-score: restorers scored on such a set
// (docs/restoration.md, study 2).
#include <vkjr2/jr2/clip_set.hpp>
#include <vkjr2/runtime/device.hpp>
#include <vkjr2/runtime/error.hpp>
#include <vkjr2/runtime/host_tensor.hpp>

#include <CLI/CLI.hpp>
#include <nlohmann/json.hpp>

#include <chrono>
#include <cstdio>
#include <filesystem>
#include <memory>
#include <span>
#include <string>
#include <vector>

#include "checks.hpp"
#include "cleanup.hpp"
#include "commands.hpp"
#include "log.hpp"
#include "progress.hpp"
#include "train_images.hpp"

namespace vkjr2::cli {
namespace {

namespace fs = std::filesystem;

double seconds_since(std::chrono::steady_clock::time_point t0) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
}

struct WaveClipArgs {
  std::string output, device;
  std::vector<std::string> images;
  std::vector<double> d_over_r0{1, 8};
  int val_every = 5;
  jr2::WaveClipOptions o;
  bool json_out = false, quiet = false, force = false;
};

void run_wave_clips(WaveClipArgs& a) {
  check_extension(a.output, {".safetensors"}, "OUT");
  check_output_file(a.output, a.force, "OUT");
  a.o.d_over_r0_lo = a.d_over_r0[0];
  a.o.d_over_r0_hi = a.d_over_r0[1];
  try {
    a.o.validate();
  } catch (const InvalidArgument& e) {
    throw UsageError("wave-clips", e.problem(), e.fix());
  }
  watch_output_folder(fs::path(a.output).parent_path());
  const auto t0 = std::chrono::steady_clock::now();
  std::vector<jr2::TrainImage> train, held_out;
  load_train_images("wave-clips", a.images, a.val_every, 0, a.o.size, train, held_out);
  const Device device = open_device(a.device);
  Progress bar("wave-clips: frames", std::size_t(a.o.clips) * std::size_t(a.o.frames), a.quiet);
  const jr2::ClipSet set = jr2::make_wave_clips(
      device, held_out, a.o, [&](int done, int) { bar.update(std::size_t(done)); });
  bar.done();
  jr2::save_clip_set(a.output, set);
  const double seconds = seconds_since(t0);
  if (a.json_out) {
    const nlohmann::json j = {{"output", a.output},
                              {"clips", set.count()},
                              {"frames", set.frames},
                              {"size", set.size},
                              {"held_out_images", held_out.size()},
                              {"d_over_r0", set.d_over_r0},
                              {"sources", set.sources},
                              {"seconds", seconds}};
    std::printf("%s\n", j.dump(2).c_str());
  } else {
    std::printf(
        "wave-clips: wrote %s: %zu clips of %d frames, %d² pixels, from %zu held-out "
        "images, in %.0f s\n",
        a.output.c_str(), set.count(), set.frames, set.size, held_out.size(), seconds);
  }
}

void add_wave_clips(CLI::App& app) {
  auto a = std::make_shared<WaveClipArgs>();
  CLI::App* cmd = app.add_subcommand(
      "wave-clips", "Make a cached test set of clips degraded by the wave-optics reference");
  cmd->footer(
      "Clip i is a centre crop of held-out image i (every --val-every-th image by name, as "
      "restore-train\n"
      "holds them out: no restorer trained with the same --images and --val-every saw them), "
      "imaged --frames\n"
      "times through the split-step wave-optics reference, each frame through its own "
      "independent screens\n"
      "(or, with --screen-motion, through the clip's screens moving between frames: frozen "
      "flow),\n"
      "at D/r0 spaced log-uniformly over --d-over-r0. Slow by design (seconds per frame); the "
      "file is the cache.\n"
      "Examples:\n"
      "  vkjr2 wave-clips out/wave_clips.safetensors\n"
      "  vkjr2 wave-clips out/wave_flow.safetensors --screen-motion 0.04\n"
      "  vkjr2 restore-score out/wave_clips.safetensors --model "
      "artifacts/restorer_default.safetensors");
  cmd->add_option("OUT", a->output, "Output clip set (.safetensors)")->required();
  cmd->add_option("--images", a->images,
                  std::string("Folders of clean images (default: ") + kDefaultTrainImages + ")");
  cmd->add_option("--val-every", a->val_every, "The held-out images: every N-th by name")
      ->default_val(a->val_every)
      ->check(CLI::Range(1, 1000));
  cmd->add_option("--clips", a->o.clips, "Clips (one per held-out image, cycling)")
      ->default_val(a->o.clips)
      ->check(CLI::Range(1, 10000));
  cmd->add_option("--frames", a->o.frames, "Frames per clip")
      ->default_val(a->o.frames)
      ->check(CLI::Range(1, 64));
  cmd->add_option("--size", a->o.size, "Clip side in pixels")
      ->default_val(a->o.size)
      ->check(CLI::Range(16, 512));
  cmd->add_option("--d-over-r0", a->d_over_r0, "D/r0 range LO HI")
      ->expected(2)
      ->default_str("1 8")
      ->check(finite_range(0.05, 20));
  cmd->add_option("--screen-motion", a->o.screen_motion_m,
                  "Frozen flow: metres the screens move per frame, in a direction drawn per clip "
                  "(0.04: tilt correlation ≈ 0.9 between frames); 0: independent screens per frame")
      ->default_val(a->o.screen_motion_m)
      ->check(finite_range(0, 10));
  cmd->add_option("--grid", a->o.wave.wave.grid, "Propagation grid N (an FFT length)")
      ->default_val(a->o.wave.wave.grid);
  cmd->add_option("--screens", a->o.wave.wave.screens, "Phase screens (at least)")
      ->default_val(a->o.wave.wave.screens)
      ->check(CLI::Range(1, 100));
  cmd->add_option("--source-step", a->o.wave.source_step_px, "Point-source spacing in pixels")
      ->default_val(a->o.wave.source_step_px)
      ->check(finite_range(1, 512));
  add_seed_option(cmd, a->o.seed, "Seed of the screens", a->o.seed);
  cmd->add_option("--device", a->device,
                  "Vulkan device: index or name substring (see vkjr2 devices)");
  cmd->add_flag("--json", a->json_out, "Print JSON instead of text");
  cmd->add_flag("--quiet", a->quiet, "No progress bar");
  cmd->add_flag("--force", a->force, "Replace an existing output file");
  cmd->callback([a] { run_wave_clips(*a); });
}

struct ScoreArgs {
  std::string clips, device, json_path;
  std::vector<std::string> models;
  jr2::ClassicalOptions classical;
  int resamples = 1000;
  bool json_out = false, force = false;
};

nlohmann::json interval_json(const jr2::Interval& i) {
  return {{"value", i.value}, {"lo", i.lo}, {"hi", i.hi}};
}

void run_restore_score(ScoreArgs& a) {
  check_input_file(a.clips, "CLIPS");
  for (const auto& m : a.models) check_input_file(m, "--model");
  if (!a.json_path.empty()) {
    check_extension(a.json_path, {".json"}, "--out");
    check_output_file(a.json_path, a.force, "--out");
  }
  const auto t0 = std::chrono::steady_clock::now();
  const jr2::ClipSet set = jr2::load_clip_set(a.clips);
  const Device device = open_device(a.device);
  std::vector<std::unique_ptr<jr2::Restorer>> nets;
  std::vector<const jr2::Restorer*> ptrs;
  std::vector<std::string> names;
  for (const auto& m : a.models) {
    nets.push_back(jr2::Restorer::load(device, m));
    ptrs.push_back(nets.back().get());
    names.push_back(fs::path(m).stem().string());
  }
  jr2::BootstrapOptions boot;
  boot.resamples = a.resamples;
  const auto rows = jr2::score_clip_set(device, set, ptrs, names, a.classical, boot);
  nlohmann::json j = {{"clips", a.clips},
                      {"count", set.count()},
                      {"frames", set.frames},
                      {"size", set.size},
                      {"source", set.metadata.count("source") ? set.metadata.at("source") : ""},
                      {"d_over_r0", set.d_over_r0},
                      {"rows", nlohmann::json::array()}};
  for (const auto& r : rows) {
    j["rows"].push_back({{"method", r.method},
                         {"psnr_db", interval_json(r.psnr_mean)},
                         {"psnr_gain_db", interval_json(r.psnr_gain)},
                         {"ssim", interval_json(r.ssim_mean)},
                         {"psnr_per_clip", r.psnr},
                         {"ssim_per_clip", r.ssim}});
  }
  j["seconds"] = seconds_since(t0);
  if (!a.json_path.empty()) {
    const std::string text = j.dump(2) + "\n";
    write_file_atomic(a.json_path, std::as_bytes(std::span(text)), "restore-score");
  }
  if (a.json_out) {
    std::printf("%s\n", j.dump(2).c_str());
    return;
  }
  std::printf(
      "restore-score: %s, %zu clips of %d frames (%s), 95%% bootstrap intervals over "
      "clips\n",
      a.clips.c_str(), set.count(), set.frames,
      set.metadata.count("source") ? set.metadata.at("source").c_str() : "?");
  std::printf("  %-28s %-24s %-24s %s\n", "method", "PSNR (dB)", "gain over degraded", "SSIM");
  for (const auto& r : rows) {
    char psnr[64], gain[64], ssim[64];
    std::snprintf(psnr, sizeof psnr, "%.2f [%.2f, %.2f]", r.psnr_mean.value, r.psnr_mean.lo,
                  r.psnr_mean.hi);
    std::snprintf(gain, sizeof gain, "%+.2f [%+.2f, %+.2f]", r.psnr_gain.value, r.psnr_gain.lo,
                  r.psnr_gain.hi);
    std::snprintf(ssim, sizeof ssim, "%.4f [%.4f, %.4f]", r.ssim_mean.value, r.ssim_mean.lo,
                  r.ssim_mean.hi);
    std::printf("  %-28s %-24s %-24s %s\n", r.method.c_str(), psnr, gain, ssim);
  }
}

void add_restore_score(CLI::App& app) {
  auto a = std::make_shared<ScoreArgs>();
  CLI::App* cmd = app.add_subcommand(
      "restore-score", "Score restorers on a cached clip set (PSNR/SSIM with intervals)");
  cmd->footer(
      "Rows: the degraded reference frame, the classical peer (temporal mean + unsharp mask), "
      "and one row per\n"
      "--model, named by its file. Each row's PSNR and SSIM are means over the clips with 95% "
      "bootstrap\n"
      "intervals; the gain is paired (the same clips), so its interval is the one to read.\n"
      "Examples:\n"
      "  vkjr2 restore-score out/wave_clips.safetensors --model "
      "artifacts/restorer_default.safetensors\n"
      "  vkjr2 restore-score clips.safetensors --model a.safetensors --model b.safetensors --out "
      "scores.json");
  cmd->add_option("CLIPS", a->clips, "A clip set (vkjr2 wave-clips)")->required();
  cmd->add_option("--model", a->models,
                  "A restorer (.safetensors from vkjr2 restore-train); repeatable");
  cmd->add_option("--classical-sigma", a->classical.sigma_px,
                  "The classical peer's unsharp-mask Gaussian σ in pixels")
      ->default_val(a->classical.sigma_px)
      ->check(finite_range(0.3, 20));
  cmd->add_option("--classical-amount", a->classical.amount, "The classical peer's sharpening")
      ->default_val(a->classical.amount)
      ->check(finite_range(0, 5));
  cmd->add_option("--resamples", a->resamples, "Bootstrap resamples of each interval")
      ->default_val(a->resamples)
      ->check(CLI::Range(10, 100000));
  cmd->add_option("--out", a->json_path, "Also write the scores as JSON to this file");
  cmd->add_option("--device", a->device,
                  "Vulkan device: index or name substring (see vkjr2 devices)");
  cmd->add_flag("--json", a->json_out, "Print JSON instead of text");
  cmd->add_flag("--force", a->force, "Replace an existing --out file");
  cmd->callback([a] { run_restore_score(*a); });
}

}  // namespace

void add_restore_study(CLI::App& app) {
  add_wave_clips(app);
  add_restore_score(app);
}

}  // namespace vkjr2::cli
