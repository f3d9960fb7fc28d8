// vkjr2 bench pipeline: probe videos per second through the JR² pipeline
// (frame sampler → detect → landmarks → align → embed → template), with the
// time per stage, against face-api on TF.js WASM doing detect + landmarks +
// descriptors on the same sampled frames, their runs interleaved with ours.
#include <vkjr2/jr2/benchmark.hpp>
#include <vkjr2/jr2/faces.hpp>
#include <vkjr2/jr2/protocol.hpp>
#include <vkjr2/jr2/sampler.hpp>
#include <vkjr2/nets/face_common.hpp>
#include <vkjr2/runtime/device.hpp>
#include <vkjr2/runtime/error.hpp>
#include <vkjr2/runtime/image.hpp>
#include <vkjr2/runtime/stream.hpp>
#include <vkjr2/sim/p2s_blur_model.hpp>
#include <vkjr2/sim/params.hpp>
#include <vkjr2/sim/simulator.hpp>

#include <CLI/CLI.hpp>
#include <nlohmann/json.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <optional>
#include <string>
#include <vector>

#include "cli/checks.hpp"
#include "cli/clips.hpp"
#include "cli/cv_image.hpp"
#include "cli/log.hpp"
#include "cli/probe_run.hpp"
#include "cli/run.hpp"
#include "harness.hpp"
#include "nets_tfjs_peer.hpp"

namespace vkjr2::cli {
namespace {

namespace fs = std::filesystem;
using nlohmann::json;

struct PipelineArgs {
  int probes = 6, frames = 30, runs = 3, clip = 160, face_px = 80;
  std::vector<double> d_over_r0 = {1.5, 3.0, 6.0};  // probe i: d_over_r0[i mod size]
  bool tfjs = true, restore = true, json_out = false;
  std::string device, json_path,
      faceapi_script = std::string(VKJR2_SOURCE_DIR) + "/bench/faceapi_bench.mjs";
};

// A probe video: its frames as a decoded 8-bit video gives them (H×W×3, 0..255).
struct Probe {
  std::string name;
  double d_over_r0 = 0;
  std::vector<HostTensor> frames;
  HostTensor clean;  // the clip before turbulence
  std::vector<int> sampled;
};

HostTensor read_rgb(const fs::path& path) {
  const cv::Mat bgr = cv::imread(path.string());
  if (bgr.empty()) {
    throw Error("bench pipeline", "cannot read " + path.string(),
                "run scripts/setup (it fetches face-api's sample photos)");
  }
  return image_from_bgr(bgr);
}

// The probes: face i of the sample photos, cut as vkjr2 dataset make cuts
// it, through `frames` frames of turbulence at D/r0 (seed i), quantized to 8
// bits as a video file holds them.
std::vector<Probe> make_probes(const Device& device, const jr2::FaceAnalyzer& analyzer,
                               const PipelineArgs& a, const jr2::FrameSampler& sampler) {
  const fs::path demo = nets::face_api_model_dir().parent_path() / "demo";
  Stream stream(device);
  std::vector<std::pair<HostTensor, nets::FaceBox>> faces;
  jr2::FaceOptions fo;
  fo.descriptors = false;
  for (int p = 1; p <= 6 && int(faces.size()) < a.probes; ++p) {
    const HostTensor photo = read_rgb(demo / ("sample" + std::to_string(p) + ".jpg"));
    for (const jr2::Face& f : analyzer.analyze(stream, nets::image_to_device(device, photo), fo)) {
      faces.emplace_back(photo, f.box);
    }
  }
  if (faces.empty())
    throw Error("bench pipeline", "no face found in the sample photos", "run scripts/setup");
  const auto blur = sim::load_shipped_blur_models(device);
  const sim::SimOptions so = jr2::probe_sim_options();
  const int c = a.clip;
  const Shape shape{1, 3, c, c};
  const Tensor x = Tensor::empty(device, shape), y = Tensor::empty(device, shape);
  std::vector<Probe> probes;
  for (int i = 0; i < a.probes; ++i) {
    const auto& [photo, box] = faces[std::size_t(i) % faces.size()];
    const HostTensor clip = face_clip(photo, box, c, a.face_px);
    x.upload(image_to_planes(clip, 3, 255.f));
    Probe probe;
    probe.name = "probe_" + std::to_string(i);
    probe.d_over_r0 = a.d_over_r0[std::size_t(i) % a.d_over_r0.size()];
    probe.clean = clip;
    sim::Simulator simulator(device, jr2::probe_sim_params(probe.d_over_r0, c), blur, so);
    simulator.reset(std::uint64_t(i) + 1);
    for (int t = 0; t < a.frames; ++t) {
      simulator.frame(stream, x, y);
      stream.run();
      // 8 bits, as a video file holds the frame.
      HostTensor frame = planes_to_image(y.download(), 3, c, c, 3, 255.f);
      for (float& v : frame.values) v = std::round(v);
      probe.frames.push_back(std::move(frame));
    }
    probe.sampled = jr2::sample_frames(a.frames, sampler, std::uint64_t(i) + 1);
    probes.push_back(std::move(probe));
  }
  return probes;
}

// The sampled frames as raw RGB for faceapi_bench.mjs --frames.
void write_frames(const fs::path& dir, const std::vector<Probe>& probes, int input_size) {
  fs::create_directories(dir);
  json index{{"input_size", input_size}, {"probes", json::array()}};
  for (const Probe& p : probes) {
    json frames = json::array();
    for (int f : p.sampled) {
      const HostTensor& img = p.frames[std::size_t(f)];
      const std::string file = p.name + "_" + std::to_string(f) + ".rgb";
      std::vector<unsigned char> bytes(img.values.size());
      for (std::size_t k = 0; k < bytes.size(); ++k)
        bytes[k] = static_cast<unsigned char>(img.values[k]);
      std::ofstream(dir / file, std::ios::binary)
          .write(reinterpret_cast<const char*>(bytes.data()), std::streamsize(bytes.size()));
      frames.push_back({{"file", file}, {"width", img.shape[1]}, {"height", img.shape[0]}});
    }
    index["probes"].push_back({{"name", p.name}, {"frames", frames}});
  }
  std::ofstream(dir / "index.json") << index.dump();
}

struct Timed {
  double seconds = 0;  // the run's wall time over all probes
  jr2::StageSeconds stages;
};

Timed run_ours(const jr2::ProbePipeline& pipeline, Stream& stream, const Device& device,
               const Probe& p, std::uint64_t seed) {
  const auto t0 = std::chrono::steady_clock::now();
  // The sampled frames are the ones the peer gets (the sampler's seed is the probe's).
  const jr2::ProbeOutcome po = pipeline.run(
      stream, int(p.frames.size()),
      [&](int f) { return nets::image_to_device(device, p.frames[std::size_t(f)]); }, seed);
  Timed t;
  t.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  t.stages = po.seconds;
  return t;
}

// One probe through a method of vkjr2 eval (restored, gated), decoded
// frames given; a fresh ProbeVideo each time, so nothing is cached between runs.
struct MethodTimed {
  double seconds = 0;
  bool restored = false;
  jr2::StageSeconds stages;
};
MethodTimed run_method_timed(ProbeContext& ctx, const Method& method, const Probe& p,
                             std::uint64_t seed) {
  ProbeVideo video(ctx.device, p.frames, nets::image_to_device(ctx.device, p.clean), p.name, seed);
  const MethodRun run = run_method(ctx, method, video);
  return {run.seconds, !run.gate || run.gate->restore, run.outcome.seconds};
}

double median(std::vector<double> v) {
  std::sort(v.begin(), v.end());
  return v.empty() ? 0 : v[v.size() / 2];
}

void run_bench_pipeline(const PipelineArgs& a) {
  DeviceOptions options;
  options.selector = a.device;
  options.validation = false;
  const Device device(options);
  const jr2::FaceAnalyzer analyzer(device);
  jr2::ProtocolOptions matched;  // face-api's work: one input size, its crop
  matched.input_sizes = {160};
  matched.aligns = {jr2::AlignMode::face_api};
  const jr2::ProtocolOptions protocol;  // vkjr2 eval's default
  const jr2::ProbePipeline ours_matched(analyzer, matched), ours_protocol(analyzer, protocol);

  std::string strengths;
  for (double d : a.d_over_r0) {
    char b[32];
    std::snprintf(b, sizeof b, "%g", d);
    strengths += (strengths.empty() ? "" : ", ") + std::string(b);
  }
  std::fprintf(stderr, "bench pipeline: making %d probe videos of %d frames (D/r0 %s)...\n",
               a.probes, a.frames, strengths.c_str());
  const std::vector<Probe> probes = make_probes(device, analyzer, a, matched.sampler);
  const fs::path frames_dir =
      fs::temp_directory_path() / ("vkjr2_bench_pipeline_" + std::to_string(::getpid()));
  write_frames(frames_dir, probes, matched.input_sizes.front());
  std::fprintf(stderr, "bench pipeline: starting face-api on TF.js...\n");
  bench::TfjsServer tfjs(a.tfjs, a.faceapi_script, {"--frames", frames_dir.string()});
  if (!tfjs.available())
    std::fprintf(stderr, "bench pipeline: no TF.js peer: %s\n", tfjs.reason().c_str());

  // The restore paths: the shipped restorer on every probe, and the shipped
  // gate deciding per probe (vkjr2 eval's restored and gated methods).
  Stream stream(device);
  std::optional<GateContext> gate_ctx;
  Method restore_all, gated;
  if (a.restore) {
    restore_all = load_method(device, "restored");
    gated = load_method(device, "gated");
    gate_ctx = gate_context(protocol, gated.gate->align());
  }
  ProbeContext ctx{device, stream, analyzer, ours_protocol, {}, gate_ctx ? &*gate_ctx : nullptr};

  std::vector<double> t_matched, t_protocol, t_tfjs, t_restore, t_gated;
  jr2::StageSeconds s_matched, s_protocol, s_restore;
  std::size_t gate_restored = 0;
  const auto add = [](jr2::StageSeconds& dst, const jr2::StageSeconds& src) {
    dst.frames += src.frames;
    dst.detect += src.detect;
    dst.landmarks += src.landmarks;
    dst.align_embed += src.align_embed;
    dst.fusion += src.fusion;
  };
  for (int r = 0; r <= a.runs; ++r) {  // run 0 warms every peer up
    double m = 0, pr = 0, tf = 0, ra = 0, ga = 0;
    jr2::StageSeconds sm, sp, sr;
    std::size_t restored = 0;
    for (std::size_t i = 0; i < probes.size(); ++i) {
      const std::uint64_t seed = std::uint64_t(i) + 1;
      const Timed tm = run_ours(ours_matched, stream, device, probes[i], seed);
      if (tfjs.available()) tf += tfjs.run(probes[i].name);
      const Timed tp = run_ours(ours_protocol, stream, device, probes[i], seed);
      m += tm.seconds;
      pr += tp.seconds;
      add(sm, tm.stages);
      add(sp, tp.stages);
      if (a.restore) {
        const MethodTimed all = run_method_timed(ctx, restore_all, probes[i], seed);
        const MethodTimed g = run_method_timed(ctx, gated, probes[i], seed);
        ra += all.seconds;
        ga += g.seconds;
        add(sr, all.stages);
        restored += g.restored ? 1 : 0;
      }
    }
    std::fprintf(stderr,
                 "bench pipeline: run %d/%d: %.2f s matched, %.2f s protocol, %.2f s face-api, "
                 "%.2f s restore-all, %.2f s gated\n",
                 r, a.runs, m, pr, tf, ra, ga);
    if (r == 0) continue;
    t_matched.push_back(m);
    t_protocol.push_back(pr);
    t_tfjs.push_back(tf);
    t_restore.push_back(ra);
    t_gated.push_back(ga);
    gate_restored = restored;  // the same decisions every run (same frames, same gate)
    if (r == 1 || m < median(t_matched)) s_matched = sm;  // stages of a typical run
    if (r == 1 || pr < median(t_protocol)) s_protocol = sp;
    if (r == 1 || ra < median(t_restore)) s_restore = sr;
  }
  std::error_code ec;
  fs::remove_all(frames_dir, ec);

  const double n = double(probes.size());
  const double peer_fps = tfjs.available() ? n / median(t_tfjs) : 0;
  const std::string peer = tfjs.available() ? "face-api TF.js WASM 1 thread, 160, 8 frames"
                                            : "face-api TF.js (unavailable)";
  std::vector<bench::Result> results = {
      {"pipeline 1 size (160), face_api crop", n / median(t_matched), "probes/s", peer, peer_fps},
      {"pipeline protocol (416,160,320; 2 aligns)", n / median(t_protocol), "probes/s", peer,
       peer_fps},
  };
  if (a.restore) {
    results.push_back({"restore-all (shipped restorer + protocol)", n / median(t_restore),
                       "probes/s", "pipeline protocol, no restoration", n / median(t_protocol)});
    results.push_back({"gated (shipped gate, restores " + std::to_string(gate_restored) + "/" +
                           std::to_string(probes.size()) + ")",
                       n / median(t_gated), "probes/s", "restore-all", n / median(t_restore)});
  }
  bench::print_table(
      "vkjr2 bench pipeline: probe videos through sampler → detect → landmarks → "
      "align → embed → template",
      device, results);
  const auto stage_row = [&](const char* name, const jr2::StageSeconds& st) {
    const double total = st.total();
    const auto ms = [&](double v) { return 1000 * v / n; };
    std::printf("%-42s %8.1f %8.1f %8.1f %8.1f %8.2f %8.1f ms/probe  (detect %.0f %%)\n", name,
                ms(st.frames), ms(st.detect), ms(st.landmarks), ms(st.align_embed), ms(st.fusion),
                ms(total), total > 0 ? 100 * st.detect / total : 0.0);
  };
  std::printf("\nper stage (ms per probe of %zu sampled frames):\n%-42s %8s %8s %8s %8s %8s %8s\n",
              probes.front().sampled.size(), "", "frames", "detect", "landmk", "align+emb",
              "template", "total");
  stage_row("1 size (160), face_api crop", s_matched);
  stage_row("protocol (416,160,320; 2 aligns)", s_protocol);
  if (a.restore) {
    stage_row("restore-all (restorer within detect)", s_restore);
    const double saved = 1 - median(t_gated) / median(t_restore);
    std::printf(
        "\ngate: restored %zu of %zu probes; %.0f %% of restore-all's time saved (the gate's "
        "features, the turbulence estimate and the sharpness, included)\n",
        gate_restored, probes.size(), 100 * saved);
  }
  std::printf(
      "\n%d probes of %d frames (%dx%d clips, D/r0 %s in turn), sampler %s; median of %d runs "
      "after 1 warm-up, the peers' runs interleaved.\nTF.js peer: %s\n",
      a.probes, a.frames, a.clip, a.clip, strengths.c_str(),
      jr2::to_string(matched.sampler).c_str(), a.runs,
      tfjs.available() ? tfjs.peer().c_str() : tfjs.reason().c_str());

  json j = bench::to_json(device, results);
  const auto stages_json = [](const jr2::StageSeconds& st, double count) {
    return json{{"frames_s", st.frames / count},       {"detect_s", st.detect / count},
                {"landmarks_s", st.landmarks / count}, {"align_embed_s", st.align_embed / count},
                {"template_s", st.fusion / count},     {"total_s", st.total() / count}};
  };
  j["stages_per_probe"] = {{"matched", stages_json(s_matched, n)},
                           {"protocol", stages_json(s_protocol, n)}};
  if (a.restore) {
    j["stages_per_probe"]["restore_all"] = stages_json(s_restore, n);
    j["gate"] = {{"restored", gate_restored},
                 {"probes", probes.size()},
                 {"seconds_per_probe", median(t_gated) / n},
                 {"restore_all_seconds_per_probe", median(t_restore) / n},
                 {"time_saved_share", 1 - median(t_gated) / median(t_restore)}};
  }
  j["probes"] = a.probes;
  j["d_over_r0"] = a.d_over_r0;
  j["frames_per_probe"] = a.frames;
  j["sampled_frames"] = probes.front().sampled.size();
  j["runs"] = a.runs;
  j["tfjs"] = tfjs.available() ? tfjs.about() : json(tfjs.reason());
  bench::emit_json(j, a.json_path, a.json_out);
}

}  // namespace
}  // namespace vkjr2::cli

namespace {

int run(int argc, char** argv) {
  using namespace vkjr2::cli;
  CLI::App app{"Probe videos/s through the JR² recognition pipeline against face-api on TF.js",
               "vkjr2 bench pipeline"};
  add_logging_options(app);
  PipelineArgs a;
  app.footer(
      "Makes --probes turbulent probe videos (face clips of the sample photos cut as vkjr2 dataset "
      "make\n"
      "cuts them), then times each through vkjr2's pipeline (sampler segments:4x2 → detect → "
      "landmarks\n"
      "→ align → descriptor → template) twice: with face-api's work (detector at 160, its crop) "
      "and with\n"
      "vkjr2 eval's protocol (416, 160, 320 pooled, both alignments); and face-api on TF.js "
      "WASM\n"
      "(node bench/faceapi_bench.mjs) running detect + landmarks + descriptors on the same sampled "
      "frames.\n"
      "Then vkjr2 eval's restored and gated methods with the shipped restorer and gate: every "
      "probe\n"
      "restored, and the gate deciding per probe (the work it saves, against restore-all).\n"
      "Prints probes/s, the ratio, and the time per stage.\n"
      "Example:\n  vkjr2 bench pipeline --json-file bench_pipeline.json\n"
      "The other benchmarks: vkjr2 bench --help (bench/RESULTS.md has the latest figures).");
  app.add_option("--probes", a.probes, "Probe videos")
      ->default_val(6)
      ->check(integer_range(1, 100));
  app.add_option("--frames", a.frames, "Frames per probe video")
      ->default_val(30)
      ->check(integer_range(8, 1000));
  app.add_option("--runs", a.runs, "Timed runs (median), after one warm-up")
      ->default_val(3)
      ->check(integer_range(1, 100));
  app.add_option("--d-over-r0", a.d_over_r0,
                 "Turbulence strengths D/r0, comma-separated: probe i gets the (i mod n)-th")
      ->delimiter(',')
      ->default_str("1.5,3,6")
      ->check(finite_range(0.1, 20.0));
  app.add_flag("!--no-restore", a.restore, "Skip the restore-all and gated paths");
  app.add_flag("!--no-tfjs", a.tfjs, "Skip the TF.js peer");
  app.add_option("--faceapi-script", a.faceapi_script, "The TF.js peer's script");
  app.add_option("--device", a.device, "Vulkan device index or name substring (else VKJR2_DEVICE)");
  app.add_option("--json-file", a.json_path, "Also write the results as JSON here");
  app.add_flag("--json", a.json_out, "Print the JSON after the table");
  app.callback([&a] { run_bench_pipeline(a); });
  return run_program(app, argc, argv);
}

}  // namespace

int main(int argc, char** argv) { return vkjr2::cli::program_main(argc, argv, run); }
