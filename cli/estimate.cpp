// vkjr2 estimate / estimate-train: the turbulence strength (D/r0, r0) of a
// video from its tilt alone (jr2/turbulence.hpp), and the calibration of that
// estimate on simulated videos of known strength.
#include <vkjr2/jr2/benchmark.hpp>
#include <vkjr2/jr2/clip_set.hpp>
#include <vkjr2/jr2/turbulence.hpp>
#include <vkjr2/runtime/device.hpp>
#include <vkjr2/runtime/error.hpp>

#include <CLI/CLI.hpp>
#include <nlohmann/json.hpp>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <map>
#include <memory>
#include <string>
#include <vector>

#include "checks.hpp"
#include "cleanup.hpp"
#include "commands.hpp"
#include "log.hpp"
#include "media.hpp"
#include "progress.hpp"
#include "registration.hpp"
#include "sim_common.hpp"

namespace vkjr2::cli {
namespace {

using json = nlohmann::ordered_json;

// One video to estimate, with its true strength when it is known.
struct Item {
  std::string name, group;  // group: the benchmark strength, or "" for plain videos
  std::filesystem::path video;
  int clip = -1;     // index into a clip set instead of a video file
  double truth = 0;  // 0: unknown
};

struct Common {
  PathArgs path;
  std::string benchmark, split, clips, device;
  int max_frames = 30;
  bool json_out = false, quiet = false;
};

void add_common(CLI::App* cmd, Common& c, const std::string& default_split) {
  cmd->add_option("--preset", c.path.preset,
                  "Optics of this preset (aperture, focal length, pixel pitch, wavelength)")
      ->default_val("moderate")
      ->check(CLI::IsMember(sim::preset_names()));
  cmd->add_option("--config", c.path.config,
                  "Optics from a simulator config file (JSON/YAML as `vkjr2 simulate`; its "
                  "turbulence is ignored)");
  cmd->add_option("--benchmark", c.benchmark,
                  "A benchmark manifest (vkjr2 dataset make): its probe videos of --split, "
                  "with their true D/r0");
  c.split = default_split;
  cmd->add_option("--split", c.split, "The benchmark split")
      ->default_val(default_split)
      ->check(CLI::IsMember({"val", "test"}));
  cmd->add_option("--clips", c.clips,
                  "A clip set (vkjr2 wave-clips): each clip with its true D/r0");
  cmd->add_option("--frames", c.max_frames, "Frames read from each video (0: all)")
      ->default_val(30)
      ->check(integer_range(0, 100000));
  cmd->add_option("--device", c.device,
                  "Vulkan device index or name substring (else VKJR2_DEVICE)");
  cmd->add_flag("--json", c.json_out, "Print JSON instead of text");
  cmd->add_flag("--quiet", c.quiet, "No progress bar");
}

std::vector<Item> collect(const Common& c, const std::vector<std::string>& videos,
                          jr2::ClipSet* set) {
  std::vector<Item> items;
  for (const std::string& v : videos) {
    check_input_file(v, "VIDEO");
    if (!is_video_path(v)) {
      throw UsageError("VIDEO", v + " is not a video (by its extension)",
                       "pass a video file (.avi, .mp4, .mov, .mkv, …)");
    }
    items.push_back({v, "", v, -1, 0});
  }
  if (!c.benchmark.empty()) {
    check_input_file(c.benchmark, "--benchmark");
    const jr2::Manifest m = jr2::read_manifest(c.benchmark);
    const std::filesystem::path dir = std::filesystem::path(c.benchmark).parent_path();
    for (const jr2::ProbeItem& p : m.probes) {
      if (p.split != c.split) continue;
      items.push_back({p.file, p.strength, dir / p.file, -1, p.d_over_r0});
    }
    if (items.empty()) {
      throw UsageError("--split", c.benchmark + " has no probe of split " + c.split,
                       "choose the other split");
    }
  }
  if (!c.clips.empty()) {
    check_input_file(c.clips, "--clips");
    *set = jr2::load_clip_set(c.clips);
    for (std::size_t i = 0; i < set->count(); ++i) {
      items.push_back({"clip " + std::to_string(i) + " (" + set->sources[i] + ")",
                       "clips",
                       {},
                       int(i),
                       set->d_over_r0[i]});
    }
  }
  if (items.empty()) {
    throw UsageError("VIDEO", "nothing to estimate",
                     "pass videos, --benchmark MANIFEST or --clips SET");
  }
  return items;
}

// Grey frames [T, H, W] (0..1) of an item.
struct GreyVideo {
  int frames = 0, height = 0, width = 0;
  std::vector<float> pixels;
};

GreyVideo load_frames(const Item& item, const jr2::ClipSet* set, int max_frames) {
  GreyVideo g;
  if (item.clip >= 0) {
    const std::size_t n = std::size_t(set->frames) * 3 * set->size * set->size;
    const std::span<const float> rgb(set->degraded.data() + std::size_t(item.clip) * n, n);
    g.frames = max_frames > 0 ? std::min(max_frames, set->frames) : set->frames;
    g.height = g.width = set->size;
    g.pixels = jr2::grey_frames(rgb.first(std::size_t(g.frames) * 3 * set->size * set->size),
                                g.frames, 3, set->size, set->size, 1.f);
    return g;
  }
  QuietDecoders quiet;
  const std::size_t t =
      read_video(item.video, 1, std::size_t(max_frames), [&](std::size_t, const Image& img) {
        if (g.height == 0) {
          g.height = int(img.shape[0]);
          g.width = int(img.shape[1]);
        }
        const std::size_t plane = std::size_t(g.height) * g.width;
        const std::size_t base = g.pixels.size();
        g.pixels.resize(base + plane);
        for (std::size_t p = 0; p < plane; ++p) {
          const float* px = img.values.data() + 3 * p;
          g.pixels[base + p] = (px[0] + px[1] + px[2]) / (3.f * 255.f);
        }
      });
  g.frames = int(t);
  return g;
}

struct Measured {
  Item item;
  jr2::TurbulenceEstimate estimate;
};

std::vector<Measured> measure_all(const Device& device, const std::vector<Item>& items,
                                  const jr2::ClipSet* set, int max_frames,
                                  const sim::Params& optics, const jr2::TurbulenceCalibration& cal,
                                  bool quiet, const char* label) {
  std::vector<Measured> out;
  Progress bar(label, items.size(), quiet || items.size() < 2);
  for (const Item& item : items) {
    const GreyVideo g = load_frames(item, set, max_frames);
    try {
      out.push_back(
          {item, estimate_grey_video(device, g.pixels, g.frames, g.height, g.width, optics, cal)});
    } catch (const InvalidArgument& e) {
      throw Error("estimate", item.name + ": " + e.problem(), e.fix());
    }
    bar.update(out.size());
  }
  bar.done();
  return out;
}

double median(std::vector<double> v) {
  std::sort(v.begin(), v.end());
  const std::size_t n = v.size();
  return n % 2 ? v[n / 2] : 0.5 * (v[n / 2 - 1] + v[n / 2]);
}

// Relative errors of the estimates with a known truth, per group and overall.
json error_summary(const std::vector<Measured>& results, bool raw) {
  std::map<std::string, std::vector<double>> groups;
  std::vector<std::string> order;
  for (const Measured& m : results) {
    if (m.item.truth <= 0) continue;
    const double est = raw ? m.estimate.raw_d_over_r0 : m.estimate.d_over_r0;
    const double err = est / m.item.truth - 1.0;
    if (!groups.count(m.item.group)) order.push_back(m.item.group);
    groups[m.item.group].push_back(err);
    if (order.size() > 1 || m.item.group != "all") groups["all"].push_back(err);
  }
  if (groups.empty()) return json();
  if (order.size() > 1) order.emplace_back("all");
  json s = json::array();
  for (const std::string& g : order) {
    const std::vector<double>& e = groups[g];
    std::vector<double> abs_err(e.size());
    std::transform(e.begin(), e.end(), abs_err.begin(), [](double x) { return std::abs(x); });
    const auto within =
        std::count_if(abs_err.begin(), abs_err.end(), [](double x) { return x <= 0.25; });
    s.push_back({{"group", g.empty() ? "videos" : g},
                 {"videos", e.size()},
                 {"median_abs_error", median(abs_err)},
                 {"max_abs_error", *std::max_element(abs_err.begin(), abs_err.end())},
                 {"median_error", median(e)},
                 {"within_25_percent", double(within) / double(e.size())}});
  }
  return s;
}

json result_json(const Measured& m) {
  json j = {{"video", m.item.name}};
  if (!m.item.group.empty()) j["group"] = m.item.group;
  j["d_over_r0"] = m.estimate.d_over_r0;
  j["r0_m"] = m.estimate.r0_m;
  if (m.estimate.tilt.frames > 0) {
    j["raw_d_over_r0"] = m.estimate.raw_d_over_r0;
    j["tilt_variance_px2"] = m.estimate.tilt.variance_px2;
    j["tilt_lag1_covariance_px2"] = m.estimate.tilt.lag1_covariance_px2;
    j["tilt_mean_variance_px2"] = m.estimate.tilt.mean_variance_px2;
    j["coverage"] = m.estimate.tilt.coverage;
  }
  if (m.estimate.spectrum.frames > 0) {
    j["spectral_fluctuation"] = m.estimate.spectrum.fluctuation;
    j["blur"] = m.estimate.blur;
    j["spectral_tiles"] = m.estimate.spectrum.tiles;
  }
  j["frames"] = std::max(m.estimate.tilt.frames, m.estimate.spectrum.frames);
  if (m.item.truth > 0) {
    j["true_d_over_r0"] = m.item.truth;
    j["error"] = m.estimate.d_over_r0 / m.item.truth - 1.0;
  }
  return j;
}

void print_summary(const json& summary, const char* what) {
  if (summary.is_null()) return;
  std::printf("%s against the true D/r0:\n", what);
  std::printf("  %-10s %6s %12s %12s %12s %10s\n", "group", "videos", "median |err|", "max |err|",
              "median err", "≤ 25 %");
  for (const json& g : summary) {
    std::printf("  %-10s %6d %11.1f%% %11.1f%% %+11.1f%% %9.0f%%\n",
                g["group"].get<std::string>().c_str(), g["videos"].get<int>(),
                100 * g["median_abs_error"].get<double>(), 100 * g["max_abs_error"].get<double>(),
                100 * g["median_error"].get<double>(), 100 * g["within_25_percent"].get<double>());
  }
}

sim::Params optics_of(const Common& c) { return params_from_args(c.path); }

// ---- vkjr2 estimate ---------------------------------------------------------

struct EstimateArgs {
  Common c;
  std::vector<std::string> videos;
  std::string calibration, out;
  bool raw = false, force = false;
};

void run_estimate(const EstimateArgs& a) {
  const sim::Params optics = optics_of(a.c);
  jr2::TurbulenceCalibration cal = jr2::TurbulenceCalibration::identity();
  if (!a.raw) {
    const std::filesystem::path cal_path = a.calibration.empty()
                                               ? jr2::default_turbulence_calibration_path()
                                               : std::filesystem::path(a.calibration);
    check_input_file(cal_path, "--calibration");
    cal = jr2::TurbulenceCalibration::load(cal_path);
  }
  if (!a.out.empty()) {
    check_output_file(a.out, a.force, "--out");
    check_extension(a.out, {".json"}, "--out");
  }
  jr2::ClipSet set;
  const std::vector<Item> items = collect(a.c, a.videos, &set);
  const Device device = open_device(a.c.device);
  const auto results =
      measure_all(device, items, &set, a.c.max_frames, optics, cal, a.c.quiet, "estimate");
  json j = {
      {"calibration", a.raw ? "none (raw)" : (a.calibration.empty() ? "shipped" : a.calibration)},
      {"cues", cal.cues()},
      {"videos", json::array()}};
  for (const Measured& m : results) j["videos"].push_back(result_json(m));
  const json summary = error_summary(results, false);
  if (!summary.is_null()) j["errors"] = summary;
  if (!a.out.empty()) {
    const std::string text = j.dump(2) + "\n";
    write_file_atomic(a.out, std::as_bytes(std::span(text.data(), text.size())), "estimate --out");
  }
  if (a.c.json_out) {
    std::printf("%s\n",
                (items.size() == 1 && summary.is_null() ? j["videos"][0] : j).dump(2).c_str());
    return;
  }
  for (const Measured& m : results) {
    const jr2::TurbulenceEstimate& e = m.estimate;
    std::printf("%s: D/r0 = %.2f, r0 = %.1f cm (", m.item.name.c_str(), e.d_over_r0, 100 * e.r0_m);
    if (e.tilt.frames > 0) {
      std::printf("tilt %.3f px rms over %d frames, %.0f %% of the frame registered",
                  std::sqrt(e.tilt.variance_px2), e.tilt.frames, 100 * e.tilt.coverage);
    }
    if (e.spectrum.frames > 0) {
      std::printf("%sspectral fluctuation %.3f over %d frames", e.tilt.frames > 0 ? "; " : "",
                  e.spectrum.fluctuation, e.spectrum.frames);
    }
    std::printf(")");
    if (m.item.truth > 0) {
      std::printf(", true %.2f (%+.0f %%)", m.item.truth,
                  100 * (m.estimate.d_over_r0 / m.item.truth - 1));
    }
    std::printf("\n");
  }
  print_summary(summary, "errors");
}

// ---- vkjr2 estimate-train ---------------------------------------------------

struct TrainArgs {
  Common c;
  std::string output, registration = "dis", cues = "spectrum";
  jr2::TiltOptions tilt;
  jr2::SpectrumOptions spectrum;
  std::vector<double> band{spectrum.band_lo, spectrum.band_hi};
  double rho = 0.9, blur_rho = 0.6;
  bool force = false;
};

// The formula a calibration applies, as text.
std::string formula(const jr2::TurbulenceCalibration& c) {
  char buf[160];
  int n = std::snprintf(buf, sizeof buf, "D/r0 = %.4f", c.gain);
  if (c.uses_tilt())
    n += std::snprintf(buf + n, sizeof buf - std::size_t(n), " · raw^%.4f", c.exponent);
  if (c.uses_spectrum()) {
    std::snprintf(buf + n, sizeof buf - std::size_t(n), " · blur^%.4f", c.blur_exponent);
  }
  return buf;
}

void run_train(TrainArgs& a) {
  a.tilt.validate();
  a.spectrum.band_lo = a.band[0];
  a.spectrum.band_hi = a.band[1];
  try {
    a.spectrum.validate();
  } catch (const InvalidArgument& e) {
    throw UsageError("--band/--tile/--stride", e.problem(), e.fix());
  }
  if (a.cues == "spectrum" && a.registration != "dis") {
    throw UsageError(
        "--registration",
        "--registration " + a.registration + " with --cues spectrum, which registers nothing",
        "add --cues tilt or --cues tilt+spectrum");
  }
  check_output_file(a.output, a.force, "OUT");
  check_extension(a.output, {".safetensors"}, "OUT");
  if (a.c.benchmark.empty() && a.c.clips.empty()) {
    throw UsageError("--benchmark", "nothing to calibrate on",
                     "pass --benchmark MANIFEST (its --split probes) or --clips SET");
  }
  const sim::Params optics = optics_of(a.c);
  jr2::ClipSet set;
  const std::vector<Item> items = collect(a.c, {}, &set);
  watch_output_folder(std::filesystem::path(a.output).parent_path());
  const Device device = open_device(a.c.device);
  // The raw measure: each cue of --cues with exponent 1 (their product is
  // what "raw" reports), then the fit of their exponents.
  jr2::TurbulenceCalibration raw_cal = jr2::TurbulenceCalibration::identity();
  raw_cal.tilt = a.tilt;
  raw_cal.tilt_correlation = a.rho;
  raw_cal.registration = a.registration;
  raw_cal.spectrum = a.spectrum;
  raw_cal.blur_correlation = a.blur_rho;
  raw_cal.exponent = a.cues == "spectrum" ? 0.0 : 1.0;
  raw_cal.blur_exponent = a.cues == "tilt" ? 0.0 : 1.0;
  auto results = measure_all(device, items, &set, a.c.max_frames, optics, raw_cal, a.c.quiet,
                             "estimate-train");
  std::vector<double> raw, blur, truth;
  for (const Measured& m : results) {
    if (raw_cal.uses_tilt()) raw.push_back(m.estimate.raw_d_over_r0);
    if (raw_cal.uses_spectrum()) blur.push_back(m.estimate.blur);
    truth.push_back(m.item.truth);
  }
  jr2::TurbulenceCalibration cal;
  try {
    cal = jr2::fit_calibration(raw_cal, raw, blur, truth);
  } catch (const InvalidArgument& e) {
    throw Error("estimate-train", e.problem(), e.fix());
  }
  // The tilt's own errors before the fit (its raw D/r0 is a D/r0).
  const json before = raw_cal.uses_tilt() ? error_summary(results, true) : json();
  for (Measured& m : results) {
    m.estimate = jr2::estimate_turbulence(m.estimate.tilt, m.estimate.spectrum, optics, cal);
  }
  const json after = error_summary(results, false);
  cal.metadata["fitted_on"] =
      a.c.benchmark.empty() ? a.c.clips : a.c.benchmark + " split " + a.c.split;
  cal.metadata["videos"] = std::to_string(results.size());
  cal.metadata["frames"] = std::to_string(a.c.max_frames);
  cal.metadata["errors"] = after.dump();
  cal.save(a.output);
  if (a.c.json_out) {
    const json j = {{"output", a.output},
                    {"cues", cal.cues()},
                    {"gain", cal.gain},
                    {"exponent", cal.exponent},
                    {"blur_exponent", cal.blur_exponent},
                    {"videos", results.size()},
                    {"raw_errors", before},
                    {"errors", after}};
    std::printf("%s\n", j.dump(2).c_str());
    return;
  }
  std::printf("estimate-train: %s from %zu videos -> %s\n", formula(cal).c_str(), results.size(),
              a.output.c_str());
  print_summary(before, "the tilt's raw (uncalibrated) errors");
  print_summary(after, "calibrated errors (on the fitting videos)");
}

}  // namespace

void add_estimate(CLI::App& app) {
  auto a = std::make_shared<EstimateArgs>();
  CLI::App* cmd = app.add_subcommand(
      "estimate", "Estimate the turbulence strength (D/r0, r0) of videos from their tilt and blur");
  cmd->footer(
      "Two cues, each with the optics' scale (--preset or --config). The tilt: the frames are\n"
      "registered against their mean (dense optical flow: OpenCV's DIS, or vkjr2's Lucas–Kanade\n"
      "kernel with a calibration fitted with --registration lk); the temporal variance of the\n"
      "displacement is the tilt variance, which the Z-tilt formula σ²_θ = 0.182 (λ/D)² "
      "(D/r0)^(5/3)\n"
      "turns into a raw D/r0. The blur: how much the power in a band of spatial frequencies (in\n"
      "units of D/λ) fluctuates from frame to frame, the median over tiles; the scene's own\n"
      "spectrum cancels. Each is corrected for the frames' correlation; a calibration fitted on\n"
      "simulated videos combines them (the shipped artifacts/turbulence_estimator.safetensors;\n"
      "vkjr2 estimate-train makes one). With --benchmark or --clips every video has a known\n"
      "D/r0 and the errors are reported.\n"
      "Examples:\n"
      "  vkjr2 estimate probe.avi --json\n"
      "  vkjr2 estimate --benchmark bench/jr2/manifest.json --split test\n"
      "  vkjr2 estimate --clips out/wave_clips.safetensors --out out/estimate_wave.json");
  cmd->add_option("VIDEO", a->videos, "Videos to estimate");
  add_common(cmd, a->c, "test");
  cmd->add_option("--calibration", a->calibration,
                  "A calibration file (vkjr2 estimate-train; default: the shipped one)");
  cmd->add_flag("--raw", a->raw, "No calibration: the Z-tilt formula's value");
  cmd->add_option("--out", a->out, "Also write the results as JSON to this file");
  cmd->add_flag("--force", a->force, "Replace an existing --out file");
  cmd->callback([a] { run_estimate(*a); });

  auto t = std::make_shared<TrainArgs>();
  CLI::App* tc = app.add_subcommand("estimate-train",
                                    "Calibrate the turbulence estimate on videos of known D/r0");
  tc->footer(
      "Measures the cues (--cues) of every probe video of a benchmark's --split (default val,\n"
      "never the test split) or of a clip set, fits D/r0 = gain · raw^a · blur^b in logs (raw:\n"
      "the tilt's D/r0, blur: the spectral fluctuation; a cue left out has exponent 0), and\n"
      "writes the calibration with its options. The errors it prints are on the fitting videos.\n"
      "Examples:\n"
      "  vkjr2 estimate-train artifacts/turbulence_estimator.safetensors \\\n"
      "      --benchmark bench/jr2/manifest.json --force   # the shipped calibration");
  tc->add_option("OUT", t->output, "Calibration file to write (.safetensors)")->required();
  add_common(tc, t->c, "val");
  tc->add_option("--registration", t->registration,
                 "dis: OpenCV's DIS optical flow on the CPU; lk: vkjr2's Lucas–Kanade kernel on "
                 "the device (vkjr2 bench estimate compares them)")
      ->default_val("dis")
      ->check(CLI::IsMember({"dis", "lk"}));
  tc->add_option("--radius", t->tilt.radius, "Texture (and lk's registration) window radius (px)")
      ->default_val(t->tilt.radius)
      ->check(integer_range(1, 32));
  tc->add_option("--iterations", t->tilt.iterations, "lk: Lucas–Kanade steps per pass")
      ->default_val(t->tilt.iterations)
      ->check(integer_range(1, 100));
  tc->add_option("--passes", t->tilt.passes, "lk: registration passes")
      ->default_val(t->tilt.passes)
      ->check(integer_range(1, 10));
  tc->add_option("--min-eigenvalue", t->tilt.min_eigenvalue,
                 "Texture threshold of a registration window (0..1 intensities per pixel, squared)")
      ->default_val(t->tilt.min_eigenvalue)
      ->check(positive_up_to(1.0));
  tc->add_option("--border", t->tilt.border, "Pixels at the frame's edge left out (px)")
      ->default_val(t->tilt.border)
      ->check(integer_range(0, 1000));
  tc->add_option("--tilt-correlation", t->rho,
                 "Frame-to-frame correlation of the tilt the variance is corrected for")
      ->default_val(t->rho)
      ->check(finite_range(0.0, 0.99));
  tc->add_option("--cues", t->cues,
                 "What the estimate reads: tilt (the frame-to-frame jitter), spectrum (the "
                 "fluctuation of the blur) or both")
      ->default_val(t->cues)
      ->check(CLI::IsMember({"tilt", "spectrum", "tilt+spectrum"}));
  tc->add_option("--band", t->band,
                 "spectrum: the spatial-frequency band LO HI, fractions of the optics' cutoff D/λ")
      ->expected(2)
      ->default_str("0.1 0.17")
      ->check(finite_range(0.0, 1.0));
  tc->add_option("--tile", t->spectrum.tile, "spectrum: tile side (px); the median over tiles")
      ->default_val(t->spectrum.tile)
      ->check(integer_range(8, 4096));
  tc->add_option("--stride", t->spectrum.stride, "spectrum: step between tiles (px)")
      ->default_val(t->spectrum.stride)
      ->check(integer_range(1, 4096));
  tc->add_option("--blur-correlation", t->blur_rho,
                 "Frame-to-frame correlation of the blur the fluctuation is corrected for")
      ->default_val(t->blur_rho)
      ->check(finite_range(0.0, 0.99));
  tc->add_flag("--force", t->force, "Replace an existing OUT");
  tc->callback([t] { run_train(*t); });
}

}  // namespace vkjr2::cli
