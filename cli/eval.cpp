// vkjr2 eval: a benchmark (vkjr2 dataset make) through the JR² protocol:
// results.json, report.md, scores.csv and the ROC, CMC and FNIR–FPIR plots.
#include <vkjr2/jr2/benchmark.hpp>
#include <vkjr2/jr2/evaluation.hpp>
#include <vkjr2/jr2/faces.hpp>
#include <vkjr2/jr2/protocol.hpp>
#include <vkjr2/jr2/restorer.hpp>
#include <vkjr2/nets/autograd.hpp>
#include <vkjr2/nets/face_common.hpp>
#include <vkjr2/nets/safetensors.hpp>
#include <vkjr2/runtime/device.hpp>
#include <vkjr2/runtime/error.hpp>
#include <vkjr2/runtime/host_tensor.hpp>
#include <vkjr2/runtime/image.hpp>

#include <CLI/CLI.hpp>
#include <nlohmann/json.hpp>

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <iterator>
#include <map>
#include <memory>
#include <set>
#include <sstream>
#include <string>
#include <vector>

#include "checks.hpp"
#include "cleanup.hpp"
#include "commands.hpp"
#include "log.hpp"
#include "media.hpp"
#include "plot.hpp"
#include "probe_run.hpp"
#include "progress.hpp"

namespace vkjr2::cli {
namespace {

namespace fs = std::filesystem;
using ojson = nlohmann::ordered_json;

struct EvalArgs {
  std::string manifest, out, device, methods = "degraded", split = "test";
  std::string frames = "segments:4x2", aligns = "face_api,similarity", fusion = "norm_weighted";
  std::string input_sizes = "416,160,320";
  int resamples = 1000, max_probes = 0;
  jr2::ClassicalOptions classical;
  std::uint64_t seed = 1;
  bool quiet = false, force = false, json_out = false;
};

constexpr std::array<const char*, 7> kOutputs = {"results.json",   "report.md", "scores.csv",
                                                 "roc.png",        "cmc.png",   "fnir_fpir.png",
                                                 "rank_change.png"};
// --method's list: comma-separated, where gated:MODEL,GATE keeps its comma.
std::vector<std::string> split_methods(const std::string& text) {
  std::vector<std::string> out;
  for (const std::string& item : split_list(text)) {
    if (!out.empty() && out.back().rfind("gated:", 0) == 0 &&
        out.back().find(',') == std::string::npos) {
      out.back() += "," + item;
    } else {
      out.push_back(item);
    }
  }
  return out;
}

jr2::ProtocolOptions protocol_from(const EvalArgs& a) {
  jr2::ProtocolOptions o;
  try {
    o.sampler = jr2::parse_frame_sampler(a.frames);
  } catch (const InvalidArgument& e) {
    throw UsageError("--frames", e.problem(), e.fix());
  }
  o.aligns.clear();
  for (const std::string& name : split_list(a.aligns)) {
    if (name == "face_api") {
      o.aligns.push_back(jr2::AlignMode::face_api);
    } else if (name == "similarity") {
      o.aligns.push_back(jr2::AlignMode::similarity);
    } else {
      throw UsageError("--align", "unknown alignment '" + name + "'",
                       "use face_api, similarity or face_api,similarity");
    }
  }
  if (a.fusion == "norm_weighted") {
    o.fusion = jr2::TemplateFusion::norm_weighted;
  } else if (a.fusion == "mean") {
    o.fusion = jr2::TemplateFusion::mean;
  } else {
    throw UsageError("--fusion", "unknown fusion '" + a.fusion + "'", "use norm_weighted or mean");
  }
  o.input_sizes.clear();
  for (const std::string& s : split_list(a.input_sizes)) {
    char* end = nullptr;
    const long v = std::strtol(s.c_str(), &end, 10);
    if (s.empty() || end != s.c_str() + s.size() || v < 32 || v > 2048 || v % 32 != 0) {
      throw UsageError("--input-sizes", "'" + s + "' is not a multiple of 32 in 32..2048",
                       "write e.g. --input-sizes 416,160,320 (the first alone is the baseline)");
    }
    o.input_sizes.push_back(int(v));
  }
  try {
    jr2::check_protocol_options(o);
  } catch (const InvalidArgument& e) {
    throw UsageError("eval", e.problem(), e.fix());
  }
  return o;
}

std::string row_label(const jr2::RowMetrics& r, bool with_method, bool with_align) {
  std::string s;
  if (with_method) s += r.method + " ";
  if (with_align) s += r.align + " ";
  return s + r.strength;
}

void write_plots(const fs::path& out, const jr2::Evaluation& e, bool force) {
  std::set<std::string> methods, aligns;
  for (const auto& r : e.rows) {
    methods.insert(r.method);
    aligns.insert(r.align);
  }
  const bool wm = methods.size() > 1, wa = aligns.size() > 1;
  // One series per row; `points` gives a row's (x, y) points.
  const auto plot = [&](PlotSpec spec, const char* file, const auto& points) {
    for (const auto& r : e.rows) spec.series.push_back({row_label(r, wm, wa), points(r)});
    write_plot(out / file, spec, force);
  };
  using Points = std::vector<std::pair<double, double>>;
  PlotSpec roc{"ROC (1:1 verification), split " + e.split, "FAR", "TAR", true};
  roc.steps = true;
  plot(roc, "roc.png", [](const jr2::RowMetrics& r) {
    Points p;
    for (const auto& q : r.roc) p.emplace_back(q.far, q.tar);
    return p;
  });
  PlotSpec cmc{"CMC (closed-set identification), split " + e.split, "rank", "identification rate"};
  cmc.x_min = 1;
  std::size_t max_rank = 2;
  for (const auto& r : e.rows) max_rank = std::max(max_rank, r.cmc.size());
  cmc.x_max = double(max_rank);
  plot(cmc, "cmc.png", [](const jr2::RowMetrics& r) {
    Points p;
    for (std::size_t k = 0; k < r.cmc.size(); ++k) p.emplace_back(double(k + 1), r.cmc[k]);
    return p;
  });
  PlotSpec det{"FNIR vs FPIR (open-set identification, rank " +
                   std::to_string(e.options.fnir_max_rank) + "), split " + e.split,
               "FPIR", "FNIR", true};
  det.steps = true;
  det.legend_top = true;
  plot(det, "fnir_fpir.png", [](const jr2::RowMetrics& r) {
    Points p;
    for (const auto& q : r.open_set) p.emplace_back(q.fpir, q.fnir);
    return p;
  });
}

// The mate's rank bin of a mated record: 0 rank 1, 1 ranks 2–5, 2 rank 6
// and beyond, 3 no face found.
int rank_bin(const jr2::ProbeRecord& r) {
  if (!r.acquired) return 3;
  const std::size_t rank = jr2::mate_rank({r.scores, r.mate});
  return rank == 1 ? 0 : rank <= 5 ? 1 : 2;
}

// rank_change.png: for every method beside degraded, how the mated probes'
// rank moved from degraded (rows) to the method (columns), in one alignment
// (similarity when evaluated). Written only when degraded is evaluated with
// another method.
void write_rank_change(const fs::path& out, const jr2::Evaluation& e,
                       const std::vector<std::string>& methods, bool force) {
  if (std::find(methods.begin(), methods.end(), "degraded") == methods.end() ||
      methods.size() < 2) {
    return;
  }
  std::string align;
  for (const auto& r : e.records) {
    if (align.empty() || r.align == "similarity") align = r.align;
  }
  std::map<std::string, int> before;  // probe file → bin, degraded
  for (const auto& r : e.records) {
    if (r.method == "degraded" && r.align == align && r.mated) before[r.file] = rank_bin(r);
  }
  MatrixSpec spec{"Rank of the mate: degraded (rows) -> method (columns); split " + e.split + ", " +
                      align + " alignment, mated probes",
                  "degraded",
                  "after",
                  {"1", "2-5", "6+", "no face"},
                  {"1", "2-5", "6+", "no face"},
                  {}};
  for (const std::string& m : methods) {
    if (m == "degraded") continue;
    MatrixPanel panel{m, std::vector<std::vector<int>>(4, std::vector<int>(4, 0))};
    for (const auto& r : e.records) {
      if (r.method != m || r.align != align || !r.mated) continue;
      const auto it = before.find(r.file);
      if (it != before.end()) ++panel.counts[std::size_t(it->second)][std::size_t(rank_bin(r))];
    }
    spec.panels.push_back(std::move(panel));
  }
  write_matrix_plot(out / "rank_change.png", spec, force);
}

void run_eval(const EvalArgs& a) {
  const auto t0 = std::chrono::steady_clock::now();
  const fs::path manifest_path(a.manifest);
  check_input_file(manifest_path, "MANIFEST");
  const fs::path out(a.out);
  check_output_folder(out, "--out");
  const std::vector<std::string> method_texts = split_methods(a.methods);
  for (const std::string& text : method_texts) (void)check_method(text);
  if (a.split != "val" && a.split != "test") {
    throw UsageError("--split", "'" + a.split + "'", "use test (the reported split) or val");
  }
  const jr2::ProtocolOptions protocol = protocol_from(a);
  // The manifest and every file it names, before any work.
  jr2::Manifest m;
  try {
    m = jr2::read_manifest(manifest_path);
  } catch (const InvalidArgument& e) {
    throw UsageError("MANIFEST", e.problem(), e.fix());
  }
  if (m.shard_count > 1) {
    throw UsageError(
        "MANIFEST",
        manifest_path.string() + " is shard " + std::to_string(m.shard_index) + " of " +
            std::to_string(m.shard_count),
        "merge the shards first: vkjr2 dataset merge " + manifest_path.parent_path().string());
  }
  const fs::path dir = manifest_path.parent_path();
  jr2::check_manifest_files(m, dir);
  std::error_code ec;
  for (const char* f : kOutputs) {
    if (fs::exists(out / f, ec)) check_output_file(out / f, a.force, "--out");
  }
  std::vector<const jr2::GalleryItem*> gallery;
  for (const auto& g : m.gallery) {
    if (g.split == a.split || g.split == "all") gallery.push_back(&g);
  }
  std::vector<const jr2::ProbeItem*> probes;
  for (const auto& p : m.probes) {
    if (p.split == a.split) probes.push_back(&p);
  }
  if (gallery.empty() || probes.empty()) {
    throw UsageError("--split",
                     "split " + a.split + " of " + manifest_path.string() + " has " +
                         std::to_string(gallery.size()) + " enrolled identities and " +
                         std::to_string(probes.size()) + " probes",
                     "evaluate a split that has both");
  }
  if (a.max_probes > 0 && std::size_t(a.max_probes) < probes.size()) {
    probes.resize(std::size_t(a.max_probes));
    log_warn("--max-probes " + std::to_string(a.max_probes) +
             ": the metrics are those of the first probes only");
  }
  create_output_folder(out, "--out");

  const Device device = open_device(a.device);
  std::vector<Method> method_list;
  std::vector<std::string> methods;
  for (const std::string& text : method_texts) {
    method_list.push_back(load_method(device, text));
    methods.push_back(method_list.back().name);
  }
  for (const Method& md : method_list) {
    if (md.align_first &&
        (protocol.aligns.size() != 1 || protocol.aligns[0] != jr2::AlignMode::similarity)) {
      throw UsageError("--method " + md.name,
                       "an align-first model restores the similarity-aligned crop",
                       "evaluate it with --align similarity");
    }
  }
  const jr2::FaceAnalyzer analyzer(device);
  const jr2::ProbePipeline pipeline(analyzer, protocol);
  Stream stream(device);
  Progress bar("eval", gallery.size() + probes.size() * methods.size(), a.quiet);
  std::size_t done = 0;

  // The gallery: one template per identity and alignment.
  std::vector<std::string> gallery_ids;
  std::map<std::string, int> gallery_index;
  std::vector<std::vector<std::vector<float>>> gallery_templates;  // [identity][align]
  for (const jr2::GalleryItem* g : gallery) {
    const Image img = read_image(dir / g->file);
    gallery_templates.push_back(pipeline.describe_gallery(stream, image_to_device(device, img)));
    gallery_index[g->identity] = int(gallery_ids.size());
    gallery_ids.push_back(g->identity);
    bar.update(++done);
  }

  std::vector<jr2::ProbeRecord> records;
  ProbeContext ctx{device, stream, analyzer, pipeline, a.classical};
  std::optional<GateContext> gate_ctx;
  for (const Method& md : method_list) {
    if (md.gate && !gate_ctx) {
      gate_ctx = gate_context(protocol, md.gate->align());
      ctx.gate = &*gate_ctx;
    }
  }
  for (std::size_t pi = 0; pi < probes.size(); ++pi) {
    const jr2::ProbeItem& p = *probes[pi];
    ProbeVideo video = read_probe_video(device, dir / p.file, dir / p.clean_file,
                                        a.seed * 0x9e3779b97f4a7c15ULL + pi);
    for (const Method& method_def : method_list) {
      const std::string& method = method_def.name;
      MethodRun run;
      try {
        run = run_method(ctx, method_def, video);
      } catch (const InvalidArgument& e) {
        throw Error("eval", p.file + ": " + e.problem(), e.fix());
      }
      const jr2::ProbeOutcome& po = run.outcome;
      const jr2::ClipQuality& quality = run.quality;
      for (std::size_t al = 0; al < protocol.aligns.size(); ++al) {
        jr2::ProbeRecord r;
        r.method = method;
        r.align = jr2::align_mode_name(protocol.aligns[al]);
        r.strength = p.strength;
        r.split = p.split;
        r.file = p.file;
        r.identity = p.identity;
        r.mated = p.mated;
        const auto it = gallery_index.find(p.identity);
        r.mate = p.mated && it != gallery_index.end() ? it->second : -1;
        r.mated = r.mate >= 0;
        r.acquired = !po.templates[al].empty();
        for (std::size_t g = 0; g < gallery_ids.size(); ++g) {
          r.scores.push_back(
              r.acquired ? jr2::cosine_similarity(po.templates[al], gallery_templates[g][al])
                         : jr2::kNoTemplateScore);
        }
        r.psnr_db = quality.psnr_db;
        r.ssim = quality.ssim;
        r.seconds = run.seconds;
        if (run.gate) r.restored = run.gate->restore ? 1 : 0;
        r.frames = int(po.frames.size());
        for (const auto& f : po.frames) {
          r.single_scale += f.single_scale ? 1 : 0;
          r.multi_scale += f.multi_scale ? 1 : 0;
          r.tracked += f.tracked ? 1 : 0;
        }
        records.push_back(std::move(r));
      }
      bar.update(++done);
    }
  }
  bar.done();

  jr2::EvaluationOptions eo;
  eo.bootstrap.resamples = a.resamples;
  eo.bootstrap.seed = a.seed;
  const jr2::Evaluation e = jr2::evaluate(gallery_ids, a.split, std::move(records), eo);
  const double seconds =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();

  std::string sizes;
  for (int s : protocol.input_sizes) sizes += (sizes.empty() ? "" : ",") + std::to_string(s);
  std::string align_names;
  for (auto al : protocol.aligns) {
    align_names += (align_names.empty() ? "" : ",") + std::string(jr2::align_mode_name(al));
  }
  const ojson setup{
      {"manifest", fs::absolute(manifest_path).string()},
      {"source", m.source_kind},
      {"identities", m.identities},
      {"split_kind", m.split_kind == jr2::SplitKind::identity ? "identity" : "realization"},
      {"benchmark_seed", m.options.seed},
      {"frames_per_probe", m.options.frames},
      {"methods", methods},
      {"sampler", jr2::to_string(protocol.sampler)},
      {"classical", {{"sigma_px", a.classical.sigma_px}, {"amount", a.classical.amount}}},
      {"input_sizes", sizes},
      {"aligns", align_names},
      {"fusion", jr2::template_fusion_name(protocol.fusion)},
      {"seed", a.seed},
      {"device", device.info().name},
      {"seconds", seconds}};
  std::ostringstream pre;
  pre << "# JR² evaluation: split " << a.split << "\n\n"
      << "Benchmark `" << manifest_path.string() << "`: " << m.identities << " identities ("
      << m.source_kind << " source), " << gallery_ids.size() << " enrolled, " << probes.size()
      << " probe videos of " << m.options.frames << " frames in this split; "
      << (m.split_kind == jr2::SplitKind::identity
              ? "val and test hold different identities."
              : "too few identities for identity-disjoint splits: val and test hold the same "
                "identities under other turbulence realizations, so thresholds chosen on val "
                "have seen these faces.")
      << "\n\nProtocol: frames " << jr2::to_string(protocol.sampler) << ", detector input sizes "
      << sizes << " (pooled) with the track, alignment " << align_names << ", templates "
      << jr2::template_fusion_name(protocol.fusion)
      << ", scores = cosine similarity of templates. Device: " << device.info().name << "; "
      << std::lround(seconds) << " s.\n";
  if (m.source_kind == "bundled") {
    pre << "\nThe bundled source has one photo per identity: a mated probe is the gallery photo "
           "itself through turbulence, so these figures measure what turbulence takes away, not "
           "recognition across pictures. With about "
        << gallery_ids.size()
        << " enrolled identities the intervals are wide; compare methods on the same probes.\n";
  }
  const std::string report = jr2::report_markdown(e, pre.str());
  const auto write_text = [&](const char* name, const std::string& text) {
    vkjr2::write_file_atomic(out / name, std::as_bytes(std::span(text)), "eval");
  };
  write_text("scores.csv", jr2::scores_csv(e));
  write_text("results.json", jr2::results_json(e, setup.dump()));
  write_plots(out, e, a.force);
  write_rank_change(out, e, methods, a.force);
  write_text("report.md", report);
  if (a.json_out) {
    std::ifstream in(out / "results.json");
    std::printf("%s", std::string(std::istreambuf_iterator<char>(in), {}).c_str());
  } else {
    std::printf(
        "%s\nwrote %s/{results.json, report.md, scores.csv, roc.png, cmc.png, "
        "fnir_fpir.png%s} in %.0f s\n",
        report.c_str(), out.string().c_str(),
        fs::exists(out / "rank_change.png") && methods.size() > 1 ? ", rank_change.png" : "",
        seconds);
  }
}

}  // namespace

void add_eval(CLI::App& app) {
  auto a = std::make_shared<EvalArgs>();
  CLI::App* cmd = app.add_subcommand(
      "eval", "Evaluate recognition on a benchmark: TAR@FAR, Rank-k, FNIR@FPIR with 95 % CIs");
  cmd->footer(
      "Reads a benchmark made by vkjr2 dataset make. Every enrolled identity's gallery clip and "
      "every probe\n"
      "video of the split goes through the JR² pipeline: frame sampler → detection at several "
      "input\n"
      "sizes pooled, with the probe's face track → 68 landmarks → alignment → descriptor →\n"
      "template; each probe template is scored (cosine similarity) against every gallery "
      "template.\n"
      "Reports, per method × alignment × strength: the detection rate (1 size / multi-size / "
      "track),\n"
      "TAR at FAR 1e-1..1e-4, Rank-1/5/20 and FNIR at FPIR 1 % and 10 % (rank 1), each with a "
      "bootstrap\n"
      "95 % interval (identities, then probes), and n/a where the benchmark is too small to "
      "measure it.\n"
      "Writes results.json, report.md, scores.csv (every comparison) and roc.png, cmc.png, "
      "fnir_fpir.png;\n"
      "with degraded and another method, rank_change.png (how each method moved the mates' "
      "ranks).\n"
      "Definitions: docs/eval.md.\n"
      "Examples:\n"
      "  vkjr2 dataset make --out bench/jr2 && vkjr2 eval bench/jr2/manifest.json --out out/eval\n"
      "  vkjr2 eval bench/jr2/manifest.json --out out/eval_val --split val --align similarity");
  cmd->add_option("MANIFEST", a->manifest, "manifest.json of a benchmark (vkjr2 dataset make)")
      ->required();
  cmd->add_option("--out", a->out, "Output folder")->required();
  cmd->add_option("--method", a->methods,
                  "Comma-separated methods: degraded (the probes as they are), classical "
                  "(temporal mean + unsharp mask), restored (the shipped restorer), "
                  "restored:MODEL.safetensors, gated:MODEL.safetensors,GATE.safetensors (the "
                  "gate of vkjr2 gate train decides per probe whether MODEL restores it) or "
                  "gated (the shipped restorer and gate)")
      ->default_val("degraded");
  cmd->add_option("--classical-sigma", a->classical.sigma_px,
                  "The classical method's unsharp-mask Gaussian σ in pixels")
      ->default_val(a->classical.sigma_px)
      ->check(finite_range(0.1, 20));
  cmd->add_option("--classical-amount", a->classical.amount,
                  "The classical method's unsharp-mask amount")
      ->default_val(a->classical.amount)
      ->check(finite_range(0, 10));
  cmd->add_option("--split", a->split, "Which split to evaluate: test or val")->default_val("test");
  cmd->add_option("--frames", a->frames, "Frame sampler: segments:SxR, uniform:K or all")
      ->default_val("segments:4x2");
  cmd->add_option("--align", a->aligns, "Alignments: face_api (box crop), similarity (5-point)")
      ->default_val("face_api,similarity");
  cmd->add_option("--fusion", a->fusion, "Template of a probe's frames: norm_weighted or mean")
      ->default_val("norm_weighted");
  cmd->add_option("--input-sizes", a->input_sizes,
                  "Detector input sizes, pooled (the first alone is the baseline)")
      ->default_val("416,160,320");
  cmd->add_option("--resamples", a->resamples, "Bootstrap resamples of each interval")
      ->default_val(1000)
      ->check(integer_range(10, 100000));
  cmd->add_option("--max-probes", a->max_probes, "Evaluate only the first N probes (a quick look)")
      ->default_val(0)
      ->check(integer_range(0, 100000000));
  add_seed_option(cmd, a->seed, "Seed of the frame sampler and the bootstrap");
  cmd->add_option("--device", a->device,
                  "Vulkan device index or name substring (else VKJR2_DEVICE)");
  cmd->add_flag("--json", a->json_out, "Print results.json instead of the report");
  cmd->add_flag("--quiet", a->quiet, "No progress bar");
  cmd->add_flag("--force", a->force, "Replace existing output files");
  cmd->callback([a] { run_eval(*a); });
}

}  // namespace vkjr2::cli
