// vkjr2 restore-train: train the restorer on clips the simulator makes on
// the fly (jr2/restore_train.hpp), with checkpoints, bit-exact resume, a JSON
// log of the losses and held-out PSNR/SSIM, and a config file.
#include <vkjr2/jr2/restore_train.hpp>
#include <vkjr2/runtime/device.hpp>
#include <vkjr2/runtime/error.hpp>
#include <vkjr2/sim/p2s_blur_model.hpp>

#include <CLI/CLI.hpp>
#include <nlohmann/json.hpp>

#include <chrono>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <map>
#include <memory>
#include <sstream>
#include <string>
#include <vector>

#include "checks.hpp"
#include "cleanup.hpp"
#include "commands.hpp"
#include "log.hpp"
#include "media.hpp"
#include "progress.hpp"
#include "sim_common.hpp"
#include "train_images.hpp"
#include "training_options.hpp"

namespace vkjr2::cli {
namespace {

namespace fs = std::filesystem;

struct TrainArgs {
  TrainRun run;
  std::string enc = "1,1,1", dec = "1,1,1";
  std::vector<std::string> images, blur_models;
  std::vector<double> d_over_r0{1, 8}, scale{0.4, 1.0};
  bool uncorrelated_high_order = false;
  int val_every = 5, video_frames = 12;
  jr2::RestoreTrainOptions o;
};

void run_restore_train(TrainArgs& a) {
  TrainRun& run = a.run;
  check_run_files(run);
  jr2::RestoreTrainOptions& o = a.o;
  o.net.enc_blocks = jr2::parse_block_list(a.enc, "--enc-blocks");
  o.net.dec_blocks = jr2::parse_block_list(a.dec, "--dec-blocks");
  o.d_over_r0_lo = a.d_over_r0[0];
  o.d_over_r0_hi = a.d_over_r0[1];
  o.scale_lo = a.scale[0];
  o.scale_hi = a.scale[1];
  o.correlate_high_order = !a.uncorrelated_high_order;
  for (const auto& path : a.blur_models) check_input_file(path, "--blur-model");
  try {
    o.validate();
  } catch (const InvalidArgument& e) {
    throw UsageError("restore-train", e.problem(), e.fix());
  }
  watch_output_folder(fs::path(run.output).parent_path());
  const auto t0 = std::chrono::steady_clock::now();
  std::vector<jr2::TrainImage> train, val;
  load_train_images("restore-train", a.images, a.val_every, a.video_frames, o.crop, train, val);
  const std::size_t n_train = train.size(), n_val = val.size();
  Device device = open_device(run.device);
  std::string blur_names = a.blur_models.empty() ? "shipped" : "";
  for (const auto& path : a.blur_models) {
    blur_names += (blur_names.empty() ? "" : ",") + fs::path(path).filename().string();
  }
  jr2::RestoreTrainer trainer(device, o, std::move(train), std::move(val),
                              load_blur_models(device, a.blur_models));
  const std::map<std::string, std::string> run_meta = {{"train.blur_models", blur_names}};
  if (run.resume) trainer.load_checkpoint(run.checkpoint);
  log_info("restore-train: " + std::to_string(n_train) + " training images, " +
           std::to_string(n_val) + " held out; " + std::to_string(o.net.parameter_count()) +
           " parameters, " + readable(o.net.flops(160, 160) / 1e9) + " GFLOP per 160² frame");

  std::ofstream log_file;
  if (!run.log_path.empty()) {
    log_file.open(run.log_path, run.resume ? std::ios::app : std::ios::trunc);
    if (!log_file) {
      throw Error("restore-train", "cannot write --log " + run.log_path, "check the folder");
    }
  }
  auto write_log = [&](const nlohmann::json& j) {
    if (log_file) log_file << j.dump() << "\n" << std::flush;
  };
  {
    Progress fill("restore-train: simulating the clip pool", std::size_t(o.pool), run.quiet);
    trainer.prepare([&](int done, int) { fill.update(std::size_t(done)); });
  }
  Progress bar("restore-train", std::size_t(o.steps), run.quiet);
  bar.update(std::size_t(trainer.step()));
  jr2::RestoreEvalReport last_eval;
  double loss_avg = 0;
  int loss_n = 0;
  auto eval = [&] {
    last_eval = trainer.evaluate();
    write_log({{"step", last_eval.step},
               {"psnr_restored", last_eval.psnr_restored},
               {"psnr_degraded", last_eval.psnr_degraded},
               {"ssim_restored", last_eval.ssim_restored},
               {"ssim_degraded", last_eval.ssim_degraded},
               {"seconds", last_eval.seconds}});
    log_info("restore-train: step " + std::to_string(last_eval.step) + ": held-out PSNR " +
             readable(last_eval.psnr_restored) + " dB (degraded " +
             readable(last_eval.psnr_degraded) + "), SSIM " + readable(last_eval.ssim_restored) +
             " (" + readable(last_eval.ssim_degraded) + "); mean train loss " +
             readable(loss_n ? loss_avg / loss_n : 0.0));
    loss_avg = 0;
    loss_n = 0;
  };
  while (trainer.step() < o.steps) {
    const jr2::RestoreStepReport r = trainer.train_step();
    loss_avg += r.loss;
    ++loss_n;
    nlohmann::json line = {{"step", r.step},
                           {"loss", r.loss},
                           {"lr", r.lr},
                           {"grad_norm", r.grad_norm},
                           {"sim_seconds", r.sim_seconds},
                           {"train_seconds", r.train_seconds}};
    if (o.explicit_weight > 0) line["consistency"] = r.consistency;
    write_log(line);
    bar.update(std::size_t(r.step));
    if (r.step % run.checkpoint_every == 0 || r.step == o.steps) {
      trainer.save_checkpoint(run.checkpoint, run_meta);
    }
    if (r.step % run.eval_every == 0 || r.step == o.steps) {
      bar.done();
      eval();
    }
  }
  bar.done();
  if (last_eval.step != trainer.step()) eval();  // resumed at the end: score what is saved
  if (device.profiling_enabled()) {
    std::fprintf(stderr, "restore-train: device time per kernel (VKJR2_PROFILE=1):\n%s",
                 device.profile_report().c_str());
  }
  const double seconds =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  auto meta = trainer.options_metadata();
  meta.insert(run_meta.begin(), run_meta.end());
  meta["train.held_out_psnr"] = readable(last_eval.psnr_restored);
  meta["train.held_out_psnr_degraded"] = readable(last_eval.psnr_degraded);
  trainer.restorer().save(run.output, meta);
  if (run.json_out) {
    const nlohmann::json j = {{"output", run.output},
                              {"checkpoint", run.checkpoint},
                              {"steps", trainer.step()},
                              {"train_images", n_train},
                              {"held_out_images", n_val},
                              {"parameters", o.net.parameter_count()},
                              {"psnr_restored", last_eval.psnr_restored},
                              {"psnr_degraded", last_eval.psnr_degraded},
                              {"ssim_restored", last_eval.ssim_restored},
                              {"ssim_degraded", last_eval.ssim_degraded},
                              {"seconds", seconds}};
    std::printf("%s\n", j.dump(2).c_str());
  } else {
    std::printf(
        "restore-train: wrote %s after %d steps in %.0f s\n  held-out PSNR %.2f dB (degraded "
        "%.2f), SSIM %.4f (%.4f)\n",
        run.output.c_str(), trainer.step(), seconds, last_eval.psnr_restored,
        last_eval.psnr_degraded, last_eval.ssim_restored, last_eval.ssim_degraded);
  }
}

}  // namespace

void add_restore_train(CLI::App& app) {
  auto a = std::make_shared<TrainArgs>();
  CLI::App* cmd = app.add_subcommand(
      "restore-train", "Train the restorer on clips the turbulence simulator makes on the fly");
  cmd->footer(
      "Clip k is made from (--seed, k): a clean image scaled, cropped to --crop² pixels and "
      "maybe mirrored,\n"
      "degraded into --frames frames at a D/r0 drawn log-uniformly in --d-over-r0. A pool of "
      "--pool clips\n"
      "is kept, --refresh of them replaced every step. Loss: Charbonnier to the clean crop; "
      "AdamW, warm-up +\n"
      "cosine decay, gradient-norm clipping. A checkpoint every --checkpoint-every steps; "
      "--resume goes on\n"
      "from it bit-exactly. Every --val-every-th image is held out and scored (PSNR/SSIM).\n"
      "Examples:\n"
      "  vkjr2 restore-train artifacts/restorer_default.safetensors --force   # the shipped "
      "model\n"
      "  vkjr2 restore-train mine.safetensors --images photos/ --steps 5000 --log train.jsonl\n"
      "  vkjr2 restore-train mine.safetensors --resume       # after an interruption\n"
      "  vkjr2 restore-train mine.safetensors --config train.yaml   # options as a JSON/YAML "
      "map");
  cmd->add_option("OUT", a->run.output, "Output model (.safetensors)")->required();
  cmd->add_option("--images", a->images,
                  "Folders of clean images and videos (default: opencv-doc's sample data)");
  cmd->add_option("--val-every", a->val_every, "Hold out every N-th image (by name)")
      ->default_val(a->val_every)
      ->check(integer_range(2, 1000));
  cmd->add_option("--video-frames", a->video_frames, "Frames taken from each video")
      ->default_val(a->video_frames)
      ->check(integer_range(1, 10000));
  auto& o = a->o;
  cmd->add_option("--frames", o.net.frames, "Input frames T")
      ->default_val(o.net.frames)
      ->check(integer_range(1, 64));
  cmd->add_option("--width", o.net.width, "Channels at full resolution")
      ->default_val(o.net.width)
      ->check(integer_range(2, 256));
  cmd->add_option("--enc-blocks", a->enc, "NAFBlocks per encoder level")->default_val(a->enc);
  cmd->add_option("--middle-blocks", o.net.middle_blocks, "NAFBlocks at the bottom")
      ->default_val(o.net.middle_blocks)
      ->check(integer_range(0, 32));
  cmd->add_option("--dec-blocks", a->dec, "NAFBlocks per decoder level, deepest first")
      ->default_val(a->dec);
  cmd->add_option("--crop", o.crop, "Training clip side in pixels")
      ->default_val(o.crop)
      ->check(integer_range(16, 512));
  cmd->add_option("--batch", o.batch, "Clips per step")
      ->default_val(o.batch)
      ->check(integer_range(1, 256));
  add_schedule_options(cmd, o);
  cmd->add_option("--d-over-r0", a->d_over_r0, "D/r0 range LO HI of the training clips")
      ->expected(2)
      ->delimiter(',')
      ->default_str("1,8")
      ->check(finite_range(0.05, 20));
  cmd->add_option("--scale", a->scale,
                  "Crop window range LO HI as a share of the image's shorter side")
      ->expected(2)
      ->delimiter(',')
      ->default_str("0.4,1")
      ->check(finite_range(0.01, 1));
  cmd->add_option("--pool", o.pool, "Simulated clips kept")
      ->default_val(o.pool)
      ->check(integer_range(1, 100000));
  cmd->add_option("--refresh", o.refresh, "New clips simulated per step")
      ->default_val(o.refresh)
      ->check(integer_range(0, 100000));
  cmd->add_option("--explicit", o.explicit_weight,
                  "Weight of the consistency loss: the restored frame re-degraded with the "
                  "input's own turbulence draws, against the input (0: off)")
      ->default_val(o.explicit_weight)
      ->check(finite_range(0.0, 100.0));
  cmd->add_flag("--uncorrelated-high-order", a->uncorrelated_high_order,
                "Simulate with the high-order modes independent between grid points (a simpler "
                "simulator, for fidelity studies)");
  cmd->add_option("--blur-model", a->blur_models,
                  "PSF basis + P2S network (.safetensors from vkjr2 sim-train) the simulator "
                  "uses; repeatable; default: the shipped ones");
  cmd->add_option("--val-clips", o.val_clips, "Held-out clips scored")
      ->default_val(o.val_clips)
      ->check(integer_range(1, 4096));
  add_run_options(cmd, a->run, "JSON-lines log of every step and score");
  add_seed_option(cmd, o.seed, "Seed of the network and the data", o.seed);
  cmd->callback([a, cmd] {
    apply_config_file(cmd, a->run.config);
    run_restore_train(*a);
  });
}

}  // namespace vkjr2::cli
