// vkjr2 cotrain: JR² co-optimization of the restorer with the recognition
// loss (jr2/cotrain.hpp), on the training split of a benchmark, with
// checkpoints, bit-exact resume, a JSON log and a config file.
#include <vkjr2/jr2/benchmark.hpp>
#include <vkjr2/jr2/clip_set.hpp>
#include <vkjr2/jr2/cotrain.hpp>
#include <vkjr2/jr2/restorer.hpp>
#include <vkjr2/nets/safetensors.hpp>
#include <vkjr2/runtime/device.hpp>
#include <vkjr2/runtime/error.hpp>
#include <vkjr2/runtime/image.hpp>

#include <CLI/CLI.hpp>
#include <nlohmann/json.hpp>

#include <chrono>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <map>
#include <memory>
#include <set>
#include <string>
#include <vector>

#include "checks.hpp"
#include "cleanup.hpp"
#include "commands.hpp"
#include "log.hpp"
#include "media.hpp"
#include "progress.hpp"
#include "sim_common.hpp"
#include "training_options.hpp"

namespace vkjr2::cli {
namespace {

namespace fs = std::filesystem;

struct CoTrainArgs {
  TrainRun run{.checkpoint_every = 50, .eval_every = 50};
  std::string benchmark, pretrained, unpaired;
  std::string order = "restore-first", layers = "all", split = "val";
  std::vector<double> d_over_r0{1, 8};
  int unpaired_frames = 12;
  int unpaired_per_identity = 0;  // 0: one wave-optics clip per training clip
  double unpaired_source_step = 16;
  jr2::CoTrainOptions o;
};

// The clean clips of a benchmark's training split: every gallery clip and
// probe clean clip of that split (gallery clips of realization splits
// belong to both), each file once, in manifest order.
std::vector<jr2::CoTrainFace> training_faces(const fs::path& manifest_path,
                                             const std::string& split) {
  const jr2::Manifest m = jr2::read_manifest(manifest_path);
  const fs::path dir = manifest_path.parent_path();
  std::vector<jr2::CoTrainFace> faces;
  std::set<std::string> seen;
  auto add = [&](const std::string& identity, const std::string& file) {
    if (file.empty() || !seen.insert(file).second) return;
    jr2::CoTrainFace f;
    f.identity = identity;
    f.source = file;
    f.clean = read_image(dir / file);
    faces.push_back(std::move(f));
  };
  for (const jr2::GalleryItem& g : m.gallery) {
    if (g.split == split || g.split == "all") add(g.identity, g.file);
  }
  for (const jr2::ProbeItem& p : m.probes) {
    if (p.split == split) add(p.identity, p.clean_file);
  }
  if (faces.empty()) {
    throw UsageError("--split", "no clips of split '" + split + "' in " + manifest_path.string(),
                     "use val (the training split) or check the manifest");
  }
  return faces;
}

// Unpaired faces from a wave-optics clip set of the training faces (made
// and saved when the file does not exist): each clip's frames, labelled by
// the face its source names. With per_identity > 0 the set holds the first
// that many training clips of each identity (in manifest order).
std::vector<jr2::CoTrainFace> unpaired_faces(const Device& device, const fs::path& path,
                                             const std::vector<jr2::CoTrainFace>& clean,
                                             const CoTrainArgs& a, bool quiet) {
  jr2::ClipSet set;
  if (fs::exists(path)) {
    set = jr2::load_clip_set(path);
  } else {
    // Before the slow part: the restorer reads a window of its T frames.
    const jr2::RestorerConfig net = jr2::RestorerConfig::from_metadata(
        nets::read_safetensors(a.pretrained).metadata, a.pretrained);
    if (a.unpaired_frames < net.frames) {
      throw UsageError("--unpaired-frames",
                       std::to_string(a.unpaired_frames) + " frames per clip, while " +
                           fs::path(a.pretrained).filename().string() + " reads " +
                           std::to_string(net.frames),
                       "pass --unpaired-frames " + std::to_string(net.frames) + " or more");
    }
    std::vector<jr2::TrainImage> images;
    std::map<std::string, int> taken;  // clips per identity so far
    for (const jr2::CoTrainFace& f : clean) {
      if (a.unpaired_per_identity > 0 && taken[f.identity]++ >= a.unpaired_per_identity) continue;
      images.push_back({f.source, f.clean});
    }
    jr2::WaveClipOptions wo;
    wo.clips = int(images.size());
    wo.frames = a.unpaired_frames;
    wo.size = int(clean.front().clean.shape[0]);
    wo.seed = a.o.seed;
    wo.wave.source_step_px = a.unpaired_source_step;
    wo.d_over_r0_lo = a.d_over_r0[0];  // the training range
    wo.d_over_r0_hi = a.d_over_r0[1];
    Progress bar("cotrain: wave-optics clips (" + path.string() + ")",
                 std::size_t(wo.clips) * std::size_t(wo.frames), quiet);
    set = jr2::make_wave_clips(device, images, wo,
                               [&](int done, int) { bar.update(std::size_t(done)); });
    bar.done();
    jr2::save_clip_set(path, set);
  }
  std::map<std::string, std::string> identity_of;
  for (const jr2::CoTrainFace& f : clean) identity_of[f.source] = f.identity;
  std::vector<jr2::CoTrainFace> out;
  const std::size_t s = std::size_t(set.size), per_frame = 3 * s * s;
  for (std::size_t i = 0; i < set.count(); ++i) {
    const auto it = identity_of.find(set.sources[i]);
    if (it == identity_of.end()) {
      throw Error("cotrain",
                  path.string() + " holds a clip of " + set.sources[i] +
                      ", not a clip of this benchmark's training split",
                  "delete it to have it made again from the training split");
    }
    jr2::CoTrainFace f;
    f.identity = it->second;
    f.source = path.filename().string() + ":" + std::to_string(i);
    for (int t = 0; t < set.frames; ++t) {
      const float* planes =
          set.degraded.data() + (i * std::size_t(set.frames) + std::size_t(t)) * per_frame;
      f.frames.push_back(planes_to_image(std::span<const float>(planes, per_frame), 3,
                                         std::int64_t(s), std::int64_t(s), 3, 255.f));
    }
    out.push_back(std::move(f));
  }
  return out;
}

nlohmann::json row_json(const jr2::CoTrainEvalReport::Row& r) {
  nlohmann::json j = {{"top1", r.top1}, {"genuine_cos", r.genuine_cos}};
  if (std::isfinite(r.psnr)) {
    j["psnr"] = r.psnr;
    j["ssim"] = r.ssim;
  }
  return j;
}

void run_cotrain(CoTrainArgs& a) {
  TrainRun& run = a.run;
  check_run_files(run);
  check_input_file(a.benchmark, "--benchmark");
  if (a.pretrained.empty()) a.pretrained = jr2::default_restorer_path().string();
  check_input_file(a.pretrained, "--pretrained");
  jr2::CoTrainOptions& o = a.o;
  try {
    o.order = jr2::parse_order(a.order);
    o.layers = jr2::parse_layer_groups(a.layers);
    o.d_over_r0_lo = a.d_over_r0[0];
    o.d_over_r0_hi = a.d_over_r0[1];
    o.validate();
  } catch (const InvalidArgument& e) {
    throw UsageError("cotrain", e.problem(), e.fix());
  }
  watch_output_folder(fs::path(run.output).parent_path());
  const auto t0 = std::chrono::steady_clock::now();
  std::vector<jr2::CoTrainFace> faces = training_faces(a.benchmark, a.split);
  Device device = open_device(run.device);
  std::vector<jr2::CoTrainFace> val = faces;  // other realizations of the same clips
  if (!a.unpaired.empty()) {
    faces = unpaired_faces(device, a.unpaired, faces, a, run.quiet);
  }
  const std::size_t n_faces = faces.size();
  jr2::CoTrainer trainer(device, o, a.pretrained, std::move(faces), std::move(val),
                         load_blur_models(device, {}));
  const std::map<std::string, std::string> run_meta = {
      {"cotrain.benchmark", fs::path(a.benchmark).filename().string()},
      {"cotrain.split", a.split},
      {"cotrain.pretrained", fs::path(a.pretrained).filename().string()},
      {"cotrain.unpaired", a.unpaired.empty() ? "" : fs::path(a.unpaired).filename().string()}};
  if (run.resume) trainer.load_checkpoint(run.checkpoint);
  log_info("cotrain: " + std::to_string(n_faces) + " training clips of " +
           std::to_string(trainer.identities().size()) + " identities, " +
           jr2::order_name(o.order) + ", λ " + readable(o.lambda) + ", layers " +
           jr2::layer_groups_name(o.layers) + ", " +
           std::to_string(trainer.trainable_parameters()) + " trainable parameters");

  std::ofstream log_file;
  if (!run.log_path.empty()) {
    log_file.open(run.log_path, run.resume ? std::ios::app : std::ios::trunc);
    if (!log_file) throw Error("cotrain", "cannot write --log " + run.log_path, "check the folder");
  }
  auto write_log = [&](const nlohmann::json& j) {
    if (log_file) log_file << j.dump() << "\n" << std::flush;
  };
  {
    nlohmann::json config;
    for (const auto& [key, value] : trainer.options_metadata()) config[key] = value;
    for (const auto& [key, value] : run_meta) config[key] = value;
    write_log({{"config", config}, {"resumed_at", trainer.step()}});
  }
  {
    Progress fill("cotrain: faces and the clip pool", std::size_t(o.pool), run.quiet);
    trainer.prepare([&](int done, int) { fill.update(std::size_t(done)); });
  }
  if (const auto& faceless = trainer.faceless_clips(); !faceless.empty()) {
    const std::vector<std::string> lost = trainer.faceless_identities();
    log_warn("cotrain: " + std::to_string(faceless.size()) + " of " + std::to_string(n_faces) +
             " unpaired clips left out: the detector finds no face in them (first: " +
             faceless.front() + ")" +
             (lost.empty() ? std::string()
                           : "; " + std::to_string(lost.size()) +
                                 " identities left without a clip are not trained on"));
    write_log({{"faceless_clips", faceless}, {"faceless_identities", lost}});
  }
  Progress bar("cotrain", std::size_t(o.steps), run.quiet);
  bar.update(std::size_t(trainer.step()));
  jr2::CoTrainEvalReport last;
  double loss_sum = 0;
  int loss_n = 0;
  auto eval = [&] {
    last = trainer.evaluate();
    write_log({{"step", last.step},
               {"student", row_json(last.student)},
               {"teacher", row_json(last.teacher)},
               {"degraded", row_json(last.degraded)},
               {"seconds", last.seconds}});
    std::string psnr;
    if (std::isfinite(last.student.psnr)) {
      psnr = ", PSNR " + readable(last.student.psnr) + " dB (teacher " +
             readable(last.teacher.psnr) + ")";
    }
    log_info("cotrain: step " + std::to_string(last.step) + ": held-out rank-1 " +
             readable(100 * last.student.top1) + " % (teacher " +
             readable(100 * last.teacher.top1) + ", degraded " +
             readable(100 * last.degraded.top1) + "), genuine cosine " +
             readable(last.student.genuine_cos) + psnr + "; mean train loss " +
             readable(loss_n ? loss_sum / loss_n : 0.0));
    loss_sum = 0;
    loss_n = 0;
  };
  while (trainer.step() < o.steps) {
    const jr2::CoTrainStepReport r = trainer.train_step();
    loss_sum += r.loss;
    ++loss_n;
    write_log({{"step", r.step},
               {"loss", r.loss},
               {"recognition", r.recognition},
               {"distillation", r.distillation},
               {"lr", r.lr},
               {"grad_norm", r.grad_norm},
               {"sim_seconds", r.sim_seconds},
               {"train_seconds", r.train_seconds},
               {"stages",
                {{"student", r.student_s},
                 {"teacher", r.teacher_s},
                 {"landmarks", r.landmarks_s},
                 {"recognize", r.recognize_s},
                 {"backward", r.backward_s},
                 {"update", r.update_s}}}});
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
  if (last.step != trainer.step()) eval();  // resumed at the end: score what is saved
  const double seconds =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  auto meta = trainer.options_metadata();
  meta.insert(run_meta.begin(), run_meta.end());
  meta["cotrain.held_out_top1"] = readable(last.student.top1);
  if (std::isfinite(last.student.psnr)) meta["cotrain.held_out_psnr"] = readable(last.student.psnr);
  trainer.student().save(run.output, meta);
  if (run.json_out) {
    const nlohmann::json j = {{"output", run.output},
                              {"checkpoint", run.checkpoint},
                              {"steps", trainer.step()},
                              {"training_clips", n_faces},
                              {"faceless_clips", trainer.faceless_clips().size()},
                              {"faceless_identities", trainer.faceless_identities().size()},
                              {"identities", trainer.identities().size()},
                              {"trainable_parameters", trainer.trainable_parameters()},
                              {"student", row_json(last.student)},
                              {"teacher", row_json(last.teacher)},
                              {"degraded", row_json(last.degraded)},
                              {"seconds", seconds}};
    std::printf("%s\n", j.dump(2).c_str());
  } else {
    std::printf(
        "cotrain: wrote %s after %d steps in %.0f s\n  held-out rank-1 %.1f %% (teacher %.1f, "
        "degraded %.1f), genuine cosine %.4f (teacher %.4f)\n",
        run.output.c_str(), trainer.step(), seconds, 100 * last.student.top1,
        100 * last.teacher.top1, 100 * last.degraded.top1, last.student.genuine_cos,
        last.teacher.genuine_cos);
    if (std::isfinite(last.student.psnr)) {
      std::printf("  held-out PSNR %.2f dB (teacher %.2f, degraded %.2f), SSIM %.4f (%.4f)\n",
                  last.student.psnr, last.teacher.psnr, last.degraded.psnr, last.student.ssim,
                  last.teacher.ssim);
    }
  }
}

}  // namespace

void add_cotrain(CLI::App& app) {
  auto a = std::make_shared<CoTrainArgs>();
  CLI::App* cmd = app.add_subcommand(
      "cotrain",
      "Co-optimize the restorer with the face-recognition loss (JR²: restore-first, "
      "self-distillation)");
  cmd->footer(
      "The student (a copy of --pretrained) restores the face window of clips of the "
      "benchmark's training\n"
      "split (its clean clips, degraded by the simulator on the fly); the restored frame goes "
      "through the\n"
      "68-point landmarks (constants), a similarity alignment and the frozen recognizer to an "
      "AdaFace head\n"
      "over the training identities. Loss: AdaFace + λ · L1 to the frozen teacher's output. "
      "Configurations:\n"
      "  --lambda 0                      fine-tune (recognition only)\n"
      "  --order align-first             align the degraded frames, restore the aligned crop\n"
      "  --layers early|middle|late|all  which layers train\n"
      "  --unpaired WAVE.safetensors     train on wave-optics clips (made if missing): labels "
      "and\n"
      "                                  self-distillation only, no clean frame\n"
      "Examples:\n"
      "  vkjr2 cotrain out/cotrain.safetensors --benchmark bench/jr2/manifest.json --log "
      "cotrain.jsonl\n"
      "  vkjr2 cotrain out/cotrain.safetensors --benchmark bench/jr2/manifest.json --resume\n"
      "  vkjr2 eval bench/jr2/manifest.json --out out/eval --method "
      "restored,restored:out/cotrain.safetensors");
  cmd->add_option("OUT", a->run.output, "Output model (.safetensors)")->required();
  cmd->add_option("--benchmark", a->benchmark, "Benchmark manifest (vkjr2 dataset make)")
      ->required();
  cmd->add_option("--split", a->split, "The benchmark's training split")->default_val(a->split);
  cmd->add_option("--pretrained", a->pretrained,
                  "The restorer to start from and distil from (default: the shipped one)");
  auto& o = a->o;
  cmd->add_option("--order", a->order, "restore-first or align-first")->default_val(a->order);
  cmd->add_option("--lambda", o.lambda, "Weight of the self-distillation L1 (0: fine-tune)")
      ->default_val(o.lambda)
      ->check(finite_range(0, 1e6));
  cmd->add_option("--layers", a->layers, "Trainable layers: all, or early,middle,late")
      ->default_val(a->layers);
  cmd->add_option("--unpaired", a->unpaired,
                  "Train on this wave-optics clip set of the training faces (made when missing)");
  cmd->add_option("--unpaired-frames", a->unpaired_frames,
                  "Frames per wave-optics clip when --unpaired makes the set")
      ->default_val(a->unpaired_frames)
      ->check(integer_range(1, 256));
  cmd->add_option("--unpaired-per-identity", a->unpaired_per_identity,
                  "Wave-optics clips per identity when --unpaired makes the set (0: one per "
                  "training clip)")
      ->default_val(a->unpaired_per_identity)
      ->check(integer_range(0, 1000));
  cmd->add_option("--unpaired-source-step", a->unpaired_source_step,
                  "Point-source spacing in pixels of the wave-optics clips --unpaired makes "
                  "(larger: faster, coarser PSF sampling)")
      ->default_val(a->unpaired_source_step)
      ->check(finite_range(1, 512));
  cmd->add_option("--window", o.window, "Restored face window side in pixels")
      ->default_val(o.window)
      ->check(integer_range(64, 512));
  cmd->add_option("--jitter", o.jitter, "Window centre jitter in pixels")
      ->default_val(o.jitter)
      ->check(integer_range(0, 64));
  cmd->add_option("--batch", o.batch, "Clips per step")
      ->default_val(o.batch)
      ->check(integer_range(2, 256));
  add_schedule_options(cmd, o);
  cmd->add_option("--d-over-r0", a->d_over_r0, "D/r0 range LO HI of the simulated clips")
      ->expected(2)
      ->delimiter(',')
      ->default_str("1,8")
      ->check(finite_range(0.05, 20));
  cmd->add_option("--pool", o.pool, "Clips kept")
      ->default_val(o.pool)
      ->check(integer_range(2, 100000));
  cmd->add_option("--refresh", o.refresh, "New clips per step")
      ->default_val(o.refresh)
      ->check(integer_range(0, 100000));
  cmd->add_option("--val-clips", o.val_clips, "Held-out clips scored")
      ->default_val(o.val_clips)
      ->check(integer_range(1, 4096));
  cmd->add_option("--adaface-m", o.adaface.m, "AdaFace margin m")
      ->default_val(o.adaface.m)
      ->check(finite_range(0, 1));
  cmd->add_option("--adaface-h", o.adaface.h, "AdaFace concentration h")
      ->default_val(o.adaface.h)
      ->check(finite_range(1e-3, 10));
  cmd->add_option("--adaface-s", o.adaface.s, "AdaFace logit scale s")
      ->default_val(o.adaface.s)
      ->check(finite_range(1e-3, 1000));
  add_run_options(cmd, a->run, "JSON-lines log: the configuration, every step, every score");
  add_seed_option(cmd, o.seed, "Seed of the head and the data", o.seed);
  cmd->callback([a, cmd] {
    apply_config_file(cmd, a->run.config);
    run_cotrain(*a);
  });
}

}  // namespace vkjr2::cli
