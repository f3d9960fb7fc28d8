// vkjr2 gate train: the restoration gate (jr2/gate.hpp), labelled by running
// the real pipeline degraded and restored on a training benchmark, its
// threshold and margin chosen on a validation split.
#include <vkjr2/jr2/benchmark.hpp>
#include <vkjr2/jr2/faces.hpp>
#include <vkjr2/jr2/gate.hpp>
#include <vkjr2/jr2/metrics.hpp>
#include <vkjr2/jr2/protocol.hpp>
#include <vkjr2/runtime/error.hpp>
#include <vkjr2/runtime/host_tensor.hpp>
#include <vkjr2/runtime/image.hpp>

#include <CLI/CLI.hpp>
#include <nlohmann/json.hpp>

#include <cmath>
#include <cstdio>
#include <fstream>
#include <iterator>
#include <limits>
#include <map>
#include <memory>
#include <sstream>
#include <string>
#include <vector>

#include "checks.hpp"
#include "commands.hpp"
#include "log.hpp"
#include "media.hpp"
#include "probe_run.hpp"
#include "progress.hpp"

namespace vkjr2::cli {
namespace {

namespace fs = std::filesystem;
using ojson = nlohmann::ordered_json;

constexpr int kSamplesVersion = 1;

struct GateArgs {
  std::string out, train = "bench/jr2_train/manifest.json", train_splits = "val,test";
  std::string validation = "bench/jr2/manifest.json", validation_split = "val";
  std::string restorer = "restored", align = "similarity", samples, device;
  jr2::GateTrainOptions options;
  std::uint64_t seed = 1;
  bool descriptor = false, quiet = false, force = false, json_out = false;
};

// One labelled set: a benchmark's probes of some splits.
struct LabelSet {
  std::string role;  // "train" or "validation"
  fs::path manifest_path;
  jr2::Manifest manifest;
  std::vector<std::string> splits;
  std::vector<const jr2::ProbeItem*> probes;
  std::vector<const jr2::GalleryItem*> gallery;
};

LabelSet open_set(const std::string& role, const std::string& path, const std::string& splits,
                  const std::string& option) {
  LabelSet s;
  s.role = role;
  s.manifest_path = path;
  check_input_file(s.manifest_path, option);
  try {
    s.manifest = jr2::read_manifest(s.manifest_path);
  } catch (const InvalidArgument& e) {
    throw UsageError(option, e.problem(), e.fix());
  }
  jr2::check_manifest_files(s.manifest, s.manifest_path.parent_path());
  s.splits = split_list(splits);
  for (const std::string& sp : s.splits) {
    if (sp != "val" && sp != "test") {
      throw UsageError(option, "split '" + sp + "'", "use val, test or val,test");
    }
  }
  for (const auto& p : s.manifest.probes) {
    if (std::find(s.splits.begin(), s.splits.end(), p.split) != s.splits.end()) {
      s.probes.push_back(&p);
    }
  }
  for (const auto& g : s.manifest.gallery) s.gallery.push_back(&g);
  if (s.probes.empty() || s.gallery.empty()) {
    throw UsageError(option,
                     path + " has " + std::to_string(s.probes.size()) + " probes in split(s) " +
                         splits + " and " + std::to_string(s.gallery.size()) +
                         " enrolled identities",
                     "give a benchmark made by vkjr2 dataset make");
  }
  return s;
}

// The mate's 1-based rank among the gallery (jr2::mate_rank: a tie ranks the
// mate below, so a probe without a template ranks last).
int mate_rank(const std::vector<float>& probe, const std::vector<std::vector<float>>& gallery,
              int mate) {
  jr2::Search search{{}, mate};
  for (const auto& g : gallery) {
    search.scores.push_back(probe.empty() ? jr2::kNoTemplateScore
                                          : jr2::cosine_similarity(probe, g));
  }
  return int(jr2::mate_rank(search));
}

ojson sample_json(const jr2::GateSample& s) {
  const jr2::GateFeatures& f = s.features;
  ojson q = nullptr;
  if (f.acquired) q = s.quality;
  return {{"file", s.file},
          {"strength", s.strength},
          {"mated", s.mated},
          {"acquired", f.acquired},
          {"descriptor", f.descriptor},
          {"descriptor_norm", f.descriptor_norm},
          {"detector_score", f.detector_score},
          {"tracked_share", f.tracked_share},
          {"d_over_r0", f.d_over_r0},
          {"sharpness", f.sharpness},
          {"quality", q},
          {"rank_raw", s.rank_raw},
          {"rank_post", s.rank_post}};
}

jr2::GateSample sample_from_json(const ojson& j) {
  jr2::GateSample s;
  s.file = j.at("file").get<std::string>();
  s.strength = j.at("strength").get<std::string>();
  s.mated = j.at("mated").get<bool>();
  jr2::GateFeatures& f = s.features;
  f.acquired = j.at("acquired").get<bool>();
  f.descriptor = j.at("descriptor").get<std::vector<float>>();
  f.descriptor_norm = j.at("descriptor_norm").get<double>();
  f.detector_score = j.at("detector_score").get<double>();
  f.tracked_share = j.at("tracked_share").get<double>();
  f.d_over_r0 = j.at("d_over_r0").get<double>();
  f.sharpness = j.at("sharpness").get<double>();
  s.quality = j.at("quality").is_null() ? std::numeric_limits<double>::quiet_NaN()
                                        : j.at("quality").get<double>();
  s.rank_raw = j.at("rank_raw").get<int>();
  s.rank_post = j.at("rank_post").get<int>();
  return s;
}

// What a cached set of labels was made from: reused only when all agree.
ojson cache_key(const LabelSet& set, const GateArgs& a, const fs::path& restorer,
                const jr2::TurbulenceCalibration& turbulence) {
  std::error_code ec;
  return {{"version", kSamplesVersion},
          {"turbulence",
           {{"cues", turbulence.cues()},
            {"gain", turbulence.gain},
            {"exponent", turbulence.exponent},
            {"blur_exponent", turbulence.blur_exponent}}},
          {"manifest", fs::absolute(set.manifest_path).string()},
          {"manifest_bytes", fs::file_size(set.manifest_path, ec)},
          {"splits", set.splits},
          {"restorer", fs::absolute(restorer).string()},
          {"restorer_bytes", fs::file_size(restorer, ec)},
          {"align", a.align},
          {"seed", a.seed}};
}

// Runs every probe of the set degraded and restored and labels it.
std::vector<jr2::GateSample> label(ProbeContext& ctx, const Method& degraded,
                                   const Method& restored, const LabelSet& set, std::uint64_t seed,
                                   bool quiet) {
  const fs::path dir = set.manifest_path.parent_path();
  const int al = ctx.gate->align_index;
  Progress bar("label " + set.role, set.gallery.size() + set.probes.size(), quiet);
  std::size_t done = 0;
  std::map<std::string, int> gallery_index;
  std::vector<std::vector<float>> gallery;
  for (const jr2::GalleryItem* g : set.gallery) {
    gallery_index[g->identity] = int(gallery.size());
    gallery.push_back(ctx.pipeline.describe_gallery(
        ctx.stream, image_to_device(ctx.device, read_image(dir / g->file)))[std::size_t(al)]);
    bar.update(++done);
  }
  std::vector<jr2::GateSample> out;
  for (std::size_t pi = 0; pi < set.probes.size(); ++pi) {
    const jr2::ProbeItem& p = *set.probes[pi];
    try {
      ProbeVideo video = read_probe_video(ctx.device, dir / p.file, dir / p.clean_file,
                                          seed * 0x9e3779b97f4a7c15ULL + pi);
      const MethodRun raw = run_method(ctx, degraded, video);
      const MethodRun post = run_method(ctx, restored, video);
      jr2::GateSample s;
      s.file = p.file;
      s.strength = p.strength;
      s.features = gate_features(ctx, video, raw.outcome);
      const std::vector<float>& t_raw = raw.outcome.templates[std::size_t(al)];
      const std::vector<float>& t_post = post.outcome.templates[std::size_t(al)];
      if (!t_raw.empty()) {
        const std::vector<float> clean =
            ctx.pipeline.describe_gallery(ctx.stream, video.clean())[std::size_t(al)];
        s.quality = jr2::cosine_similarity(t_raw, clean);
      } else {
        s.quality = std::numeric_limits<double>::quiet_NaN();
      }
      const auto mate = gallery_index.find(p.identity);
      s.mated = p.mated && mate != gallery_index.end();
      if (s.mated) {
        s.rank_raw = mate_rank(t_raw, gallery, mate->second);
        s.rank_post = mate_rank(t_post, gallery, mate->second);
      }
      out.push_back(std::move(s));
    } catch (const InvalidArgument& e) {
      throw Error("gate train", (dir / p.file).string() + ": " + e.problem(), e.fix());
    }
    bar.update(++done);
  }
  bar.done();
  return out;
}

// The labels of a set: from the cache when it was made from the same inputs.
std::vector<jr2::GateSample> labels_of(ProbeContext& ctx, const Method& degraded,
                                       const Method& restored, const LabelSet& set,
                                       const GateArgs& a, const fs::path& restorer, ojson& cache) {
  const ojson key = cache_key(set, a, restorer, ctx.gate->calibration);
  if (cache.contains(set.role) && cache[set.role].value("key", ojson()) == key) {
    std::vector<jr2::GateSample> out;
    try {
      for (const ojson& j : cache[set.role].at("samples")) out.push_back(sample_from_json(j));
      log_info("gate train: the " + set.role + " labels come from " + a.samples);
      return out;
    } catch (const nlohmann::json::exception& e) {
      log_warn(a.samples + " is not readable (" + e.what() + "): labelling again");
    }
  }
  std::vector<jr2::GateSample> out = label(ctx, degraded, restored, set, a.seed, a.quiet);
  ojson samples = ojson::array();
  for (const jr2::GateSample& s : out) samples.push_back(sample_json(s));
  cache[set.role] = {{"key", key}, {"samples", samples}};
  if (!a.samples.empty()) {
    const std::string text = cache.dump() + "\n";
    write_file_atomic(a.samples, std::as_bytes(std::span(text)), "gate train");
  }
  return out;
}

ojson outcome_json(const jr2::GateOutcome& o) {
  return {
      {"probes", o.probes},
      {"restored", o.restored},
      {"skipped_share", o.probes ? double(o.probes - o.restored) / double(o.probes) : 0.0},
      {"mated", o.mated},
      {"mrr", {{"degraded", o.mrr_degraded}, {"restored", o.mrr_restored}, {"gated", o.mrr_gated}}},
      {"rank1",
       {{"degraded", o.rank1_degraded}, {"restored", o.rank1_restored}, {"gated", o.rank1_gated}}}};
}

// Per strength (and all), what the gate does on a labelled set.
ojson outcome_table(Stream& stream, const jr2::Gate& gate,
                    const std::vector<jr2::GateSample>& samples) {
  std::vector<std::string> strengths;
  for (const auto& s : samples) {
    if (std::find(strengths.begin(), strengths.end(), s.strength) == strengths.end()) {
      strengths.push_back(s.strength);
    }
  }
  strengths.emplace_back("all");
  ojson t = ojson::object();
  for (const std::string& st : strengths) {
    std::vector<jr2::GateSample> part;
    for (const auto& s : samples) {
      if (st == "all" || s.strength == st) part.push_back(s);
    }
    t[st] = outcome_json(gate.outcome(stream, part));
  }
  return t;
}

void print_table(const char* title, const ojson& t) {
  std::printf("%s\n  %-9s %6s %8s %8s   %-24s %s\n", title, "strength", "probes", "restored",
              "skipped", "MRR degraded/all/gated", "Rank-1 degraded/all/gated (of mated)");
  for (const auto& [st, o] : t.items()) {
    std::printf("  %-9s %6zu %8zu %7.0f%%   %.3f / %.3f / %.3f      %zu / %zu / %zu (of %zu)\n",
                st.c_str(), o["probes"].get<std::size_t>(), o["restored"].get<std::size_t>(),
                100 * o["skipped_share"].get<double>(), o["mrr"]["degraded"].get<double>(),
                o["mrr"]["restored"].get<double>(), o["mrr"]["gated"].get<double>(),
                o["rank1"]["degraded"].get<std::size_t>(),
                o["rank1"]["restored"].get<std::size_t>(), o["rank1"]["gated"].get<std::size_t>(),
                o["mated"].get<std::size_t>());
  }
}

void run_gate_train(const GateArgs& a) {
  const fs::path out(a.out);
  check_output_file(out, a.force, "OUT");
  check_extension(out, {".safetensors"}, "OUT");
  if (!a.samples.empty()) check_extension(a.samples, {".json"}, "--samples");
  jr2::AlignMode align = jr2::AlignMode::similarity;
  if (a.align == "face_api") {
    align = jr2::AlignMode::face_api;
  } else if (a.align != "similarity") {
    throw UsageError("--align", "unknown alignment '" + a.align + "'",
                     "use similarity or face_api");
  }
  jr2::GateTrainOptions options = a.options;
  options.descriptor = a.descriptor;
  try {
    options.validate();
  } catch (const InvalidArgument& e) {
    throw UsageError("gate train", e.problem(), e.fix());
  }
  const std::string method_text =
      a.restorer == "restored" ? std::string("restored") : "restored:" + a.restorer;
  const std::vector<fs::path> restorer_files = check_method(method_text);
  const LabelSet train = open_set("train", a.train, a.train_splits, "--train");
  const LabelSet val = open_set("validation", a.validation, a.validation_split, "--validation");
  if (fs::absolute(train.manifest_path) == fs::absolute(val.manifest_path)) {
    for (const std::string& sp : train.splits) {
      if (std::find(val.splits.begin(), val.splits.end(), sp) != val.splits.end()) {
        throw UsageError("--validation-split",
                         "split " + sp + " of " + a.train + " is both trained and validated on",
                         "validate on a split the gate is not trained on");
      }
    }
  }
  ojson cache = ojson::object();
  if (!a.samples.empty() && fs::exists(a.samples)) {
    std::ifstream in(a.samples);
    cache = ojson::parse(in, nullptr, false);
    if (cache.is_discarded() || !cache.is_object()) {
      log_warn(a.samples + " is not a label file: labelling again and replacing it");
      cache = ojson::object();
    }
  }

  const Device device = open_device(a.device);
  jr2::ProtocolOptions protocol;
  protocol.aligns = {align};
  const jr2::FaceAnalyzer analyzer(device);
  const jr2::ProbePipeline pipeline(analyzer, protocol);
  Stream stream(device);
  const GateContext gctx = gate_context(protocol, align);
  ProbeContext ctx{device, stream, analyzer, pipeline, {}, &gctx};
  const Method degraded = load_method(device, "degraded");
  const Method restored = load_method(device, method_text);
  const std::vector<jr2::GateSample> train_samples =
      labels_of(ctx, degraded, restored, train, a, restorer_files[0], cache);
  const std::vector<jr2::GateSample> val_samples =
      labels_of(ctx, degraded, restored, val, a, restorer_files[0], cache);

  jr2::Gate gate = [&] {
    try {
      return jr2::Gate::train(device, train_samples, options);
    } catch (const InvalidArgument& e) {
      throw Error("gate train", a.train + ": " + e.problem(), e.fix());
    }
  }();
  gate.set_align(align);
  const jr2::GateOutcome chosen = gate.choose_thresholds(stream, val_samples);
  const ojson train_table = outcome_table(stream, gate, train_samples);
  const ojson val_table = outcome_table(stream, gate, val_samples);

  gate.metadata["restorer"] = restorer_files[0].filename().string();
  gate.metadata["train.manifest"] = a.train;
  gate.metadata["train.splits"] = a.train_splits;
  gate.metadata["train.probes"] = std::to_string(train_samples.size());
  gate.metadata["validation.manifest"] = a.validation;
  gate.metadata["validation.split"] = a.validation_split;
  gate.metadata["validation.outcome"] = val_table.dump();
  gate.save(out);

  const ojson summary{{"gate", out.string()},
                      {"quality_threshold", chosen.quality_threshold},
                      {"rank_margin", chosen.rank_margin},
                      {"train", train_table},
                      {"validation", val_table}};
  if (a.json_out) {
    std::printf("%s\n", summary.dump(1).c_str());
    return;
  }
  std::printf(
      "gate: restore when the predicted quality < %.4f and the predicted rank label >= "
      "1/e - %.2f (chosen on the validation split)\n",
      chosen.quality_threshold, chosen.rank_margin);
  print_table("train (fit):", train_table);
  print_table("validation (threshold chosen here):", val_table);
  std::printf("wrote %s\n", out.string().c_str());
}

}  // namespace

void add_gate(CLI::App& app) {
  CLI::App* cmd =
      app.add_subcommand("gate", "The restoration gate: decides per probe whether to restore");
  cmd->require_subcommand(1);
  auto a = std::make_shared<GateArgs>();
  CLI::App* train = cmd->add_subcommand("train", "Train the gate on labels from the real pipeline");
  train->footer(
      "Labels: every probe of the training benchmark (--train, its --train-splits) goes through "
      "the "
      "JR²\n"
      "pipeline degraded and restored (--restorer). The score head learns the quality proxy (the "
      "cosine\n"
      "similarity of the degraded template to the clean face's), the rank head the rank-change "
      "label\n"
      "exp((r_raw - r_post)/r_raw - 1) with the seed paper's re-weighting. Features: the "
      "descriptors' norm,\n"
      "the detector score, the tracked share, the estimated D/r0 (vkjr2 estimate), the face's "
      "sharpness\n"
      "and, with --descriptor, the degraded template. The threshold and margin are chosen on\n"
      "--validation's --validation-split (the mated probes' mean reciprocal rank, then the fewest "
      "restored).\n"
      "--samples caches the labels (reused when made from the same benchmark, splits, restorer, "
      "alignment\n"
      "and seed). A probe without a face found is always restored. docs/jr2.md §8.\n"
      "Examples:\n"
      "  vkjr2 dataset make --out bench/jr2_train --seed 2\n"
      "  vkjr2 gate train artifacts/gate.safetensors --train bench/jr2_train/manifest.json \\\n"
      "      --validation bench/jr2/manifest.json --samples out/gate/labels.json\n"
      "  vkjr2 eval bench/jr2/manifest.json --out out/gated --align similarity \\\n"
      "      --method "
      "degraded,restored,gated:artifacts/restorer_default.safetensors,artifacts/gate.safetensors");
  train->add_option("OUT", a->out, "The gate file to write (.safetensors)")->required();
  train->add_option("--train", a->train, "Training benchmark: manifest.json of vkjr2 dataset make")
      ->default_val(a->train);
  train->add_option("--train-splits", a->train_splits, "Its splits to train on")
      ->default_val(a->train_splits);
  train
      ->add_option("--validation", a->validation,
                   "Benchmark whose split chooses the threshold (never the reported one)")
      ->default_val(a->validation);
  train->add_option("--validation-split", a->validation_split, "Its split: val")
      ->default_val(a->validation_split);
  train
      ->add_option(
          "--restorer", a->restorer,
          "The restorer the gate decides for: restored (the shipped one) or MODEL.safetensors")
      ->default_val(a->restorer);
  train->add_option("--align", a->align, "The alignment whose template the gate reads")
      ->default_val(a->align);
  train->add_option("--samples", a->samples,
                    "Label cache (.json): read when it matches, else written");
  train->add_option("--hidden", a->options.hidden, "Hidden units of each head")
      ->default_val(a->options.hidden)
      ->check(integer_range(1, 1024));
  train->add_option("--steps", a->options.steps, "Full-batch AdamW steps")
      ->default_val(a->options.steps)
      ->check(integer_range(1, 1000000));
  train->add_option("--lr", a->options.lr, "Learning rate")
      ->default_val(a->options.lr)
      ->check(finite_range(1e-6, 0.5));
  train->add_option("--weight-decay", a->options.weight_decay, "AdamW weight decay")
      ->default_val(a->options.weight_decay)
      ->check(finite_range(0, 0.9));
  train
      ->add_option("--weight-floor", a->options.weight_floor,
                   "Smallest rank-sample weight (the re-weighting is negative in places)")
      ->default_val(a->options.weight_floor)
      ->check(finite_range(1e-3, 10));
  train->add_flag("--descriptor", a->descriptor,
                  "Feed the 128 template values to the heads too (else the 5 summary features)");
  add_seed_option(train, a->seed, "Seed of the frame sampler (as vkjr2 eval's --seed)");
  train->add_option("--init-seed", a->options.seed, "Seed of the heads' initial weights")
      ->default_val(a->options.seed);
  train->add_option("--device", a->device,
                    "Vulkan device index or name substring (else VKJR2_DEVICE)");
  train->add_flag("--json", a->json_out, "Print a JSON summary");
  train->add_flag("--quiet", a->quiet, "No progress bar");
  train->add_flag("--force", a->force, "Replace an existing OUT");
  train->callback([a] { run_gate_train(*a); });
}

}  // namespace vkjr2::cli
