// vkjr2 demo: the JR² study with the shipped artifacts, end to end: a small
// benchmark, its test split through degraded / + restoration / + gate /
// + co-optimization, the summary table, a montage, the plots and a restored
// video, in out/demo/.
#include <vkjr2/jr2/benchmark.hpp>
#include <vkjr2/jr2/faces.hpp>
#include <vkjr2/jr2/restorer.hpp>
#include <vkjr2/jr2/turbulence.hpp>
#include <vkjr2/nets/autograd.hpp>
#include <vkjr2/nets/safetensors.hpp>
#include <vkjr2/runtime/device.hpp>
#include <vkjr2/runtime/error.hpp>
#include <vkjr2/runtime/image.hpp>

#include <CLI/CLI.hpp>
#include <fcntl.h>
#include <nlohmann/json.hpp>
#include <opencv2/imgproc.hpp>
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <map>
#include <memory>
#include <sstream>
#include <string>
#include <vector>

#include "checks.hpp"
#include "cleanup.hpp"
#include "commands.hpp"
#include "cv_image.hpp"
#include "log.hpp"
#include "media.hpp"
#include "plot.hpp"

namespace vkjr2::cli {
namespace {

namespace fs = std::filesystem;
using ojson = nlohmann::ordered_json;

struct Jr2DemoArgs {
  std::string out = "out/demo", device, cotrain_study = "out/cotrain";
  int identities = 5, frames = 30, clip = 160, face_px = 80, montage = 4, resamples = 1000;
  std::uint64_t seed = 1;
  bool quiet = false, force = false, json_out = false;
};

// The configurations of the paper's summary table, as vkjr2 eval names them.
struct Config {
  const char* label;   // in the table
  std::string method;  // eval's --method item
  std::string row;     // eval's method name in results.json
};

fs::path artifact(const char* name) { return jr2::default_restorer_path().parent_path() / name; }

double seconds_since(std::chrono::steady_clock::time_point t0) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
}

// Runs this program with `args` (a step of the study) and waits for it;
// its progress and messages go to the terminal. Throws Error naming the
// step when it fails.
void run_step(const std::string& step, std::vector<std::string> args) {
  std::error_code ec;
  const fs::path self = fs::read_symlink("/proc/self/exe", ec);
  if (ec) throw Error("demo", "cannot find the vkjr2 program itself: " + ec.message(), "");
  args.insert(args.begin(), "vkjr2");
  std::vector<char*> argv;
  for (std::string& a : args) argv.push_back(a.data());
  argv.push_back(nullptr);
  std::fflush(stdout);
  std::fflush(stderr);
  const pid_t pid = ::fork();
  if (pid < 0) throw Error("demo", std::string("cannot start a step: ") + std::strerror(errno), "");
  if (pid == 0) {
    // The step's own report goes unseen (the demo writes its own); its
    // progress bars and errors go to stderr.
    const int null = ::open("/dev/null", O_WRONLY);
    if (null >= 0) ::dup2(null, STDOUT_FILENO);
    sigset_t none;  // the step handles its own signals
    sigemptyset(&none);
    pthread_sigmask(SIG_SETMASK, &none, nullptr);
    ::execv(self.c_str(), argv.data());
    std::_Exit(127);
  }
  int status = 0;
  while (::waitpid(pid, &status, 0) < 0 && errno == EINTR) {
  }
  if (!WIFEXITED(status) || WEXITSTATUS(status) != 0) {
    std::string line;
    for (std::size_t i = 0; i + 1 < argv.size(); ++i) line += (i ? " " : "") + args[i];
    throw Error("demo",
                "step '" + step + "' failed (" +
                    (WIFEXITED(status) ? "exit code " + std::to_string(WEXITSTATUS(status))
                                       : std::string("killed by a signal")) +
                    "): " + line,
                "see its message above; run the step alone to look closer");
  }
}

// The top gallery match of a probe under a method: identity and score.
struct Match {
  std::string identity;
  double score = -2;
};

// The fields of a CSV line (RFC 4180 quoting: "a,b" and "" inside quotes).
std::vector<std::string> csv_fields(const std::string& line) {
  std::vector<std::string> out(1);
  bool quoted = false;
  for (std::size_t i = 0; i < line.size(); ++i) {
    const char c = line[i];
    if (quoted && c == '"' && i + 1 < line.size() && line[i + 1] == '"') {
      out.back() += '"';
      ++i;
    } else if (c == '"') {
      quoted = !quoted;
    } else if (c == ',' && !quoted) {
      out.emplace_back();
    } else {
      out.back() += c;
    }
  }
  return out;
}

// scores.csv → (method, probe) → the top match (similarity alignment).
std::map<std::pair<std::string, std::string>, Match> top_matches(const fs::path& csv) {
  std::ifstream in(csv);
  std::map<std::pair<std::string, std::string>, Match> out;
  std::string line;
  std::getline(in, line);  // header
  while (std::getline(in, line)) {
    const std::vector<std::string> f = csv_fields(line);
    if (f.size() != 7 || f[1] != "similarity") continue;
    Match& m = out[{f[0], f[3]}];
    const double s = std::strtod(f[5].c_str(), nullptr);
    if (m.identity.empty() || s > m.score) m = {f[4], s};
  }
  return out;
}

cv::Mat tile(const HostTensor& rgb, int side, const std::string& top, const std::string& bottom,
             const cv::Scalar& colour) {
  cv::Mat bgr = image_to_bgr(rgb), big;
  cv::resize(bgr, big, {side, side}, 0, 0, cv::INTER_CUBIC);
  cv::Mat t(side + 44, side, CV_8UC3, cv::Scalar(255, 255, 255));
  big.copyTo(t(cv::Rect(0, 0, side, side)));
  cv::putText(t, top, {4, side + 17}, cv::FONT_HERSHEY_SIMPLEX, 0.45, colour, 1, cv::LINE_AA);
  cv::putText(t, bottom, {4, side + 37}, cv::FONT_HERSHEY_SIMPLEX, 0.45, colour, 1, cv::LINE_AA);
  return t;
}

// One restored frame: frame `f` of the video from the restorer's window.
HostTensor restore_frame(const Device& device, const jr2::Restorer& net,
                         const std::vector<HostTensor>& frames, std::size_t f) {
  Stream stream(device);
  std::vector<Tensor> window;
  for (std::size_t i : jr2::restore_window(frames.size(), f, net.config().frames)) {
    window.push_back(image_to_device(device, frames[i], 3, 255.f));
  }
  nets::Tape tape(stream, false);
  const Tensor out = jr2::to_pixels(
      stream, net.forward(tape, nets::Var(jr2::stack_frames(stream, window))).value());
  stream.run();
  return image_to_host(out);
}

// montage.png: per shown probe, clean | degraded | restored | co-optimized,
// each labelled with the method's top match (green when it is the probe's
// identity) and its score.
void write_montage(const Jr2DemoArgs& a, const fs::path& bench, const jr2::Manifest& m,
                   const std::vector<Config>& configs, const fs::path& scores) {
  const auto matches = top_matches(scores);
  std::vector<const jr2::ProbeItem*> shown;
  for (const char* strength : {"strong", "moderate", "weak"}) {
    for (const auto& p : m.probes) {
      if (p.split == "test" && p.mated && p.strength == strength && int(shown.size()) < a.montage) {
        shown.push_back(&p);
      }
    }
  }
  if (shown.empty()) return;
  const Device device = open_device(a.device);
  const auto restorer = jr2::Restorer::load(device, artifact("restorer_default.safetensors"));
  const auto cotrained = jr2::Restorer::load(device, artifact("restorer_cotrained.safetensors"));
  constexpr int kSide = 200;
  std::vector<cv::Mat> rows;
  cv::Mat header(30, 4 * kSide, CV_8UC3, cv::Scalar(255, 255, 255));
  const char* names[] = {"clean", "degraded", "restored", "co-optimized"};
  for (int c = 0; c < 4; ++c) {
    cv::putText(header, names[c], {c * kSide + 6, 21}, cv::FONT_HERSHEY_SIMPLEX, 0.55,
                cv::Scalar(0, 0, 0), 1, cv::LINE_AA);
  }
  rows.push_back(header);
  for (const jr2::ProbeItem* p : shown) {
    std::vector<HostTensor> frames;
    read_video(bench / p->file, 1, 0,
               [&](std::size_t, const Image& img) { frames.push_back(img); });
    const std::size_t mid = frames.size() / 2;
    const std::vector<HostTensor> images = {read_image(bench / p->clean_file), frames[mid],
                                            restore_frame(device, *restorer, frames, mid),
                                            restore_frame(device, *cotrained, frames, mid)};
    // The clean tile names the probe; the others the match of degraded,
    // + restoration and co-optimized (+ gate).
    const std::array<int, 4> config_of = {-1, 0, 1, 3};
    std::vector<cv::Mat> tiles;
    for (int c = 0; c < 4; ++c) {
      if (config_of[std::size_t(c)] < 0) {
        char d[48];
        std::snprintf(d, sizeof d, "%s, D/r0 %.1f", p->strength.c_str(), p->d_over_r0);
        tiles.push_back(tile(images[0], kSide, p->identity, d, cv::Scalar(60, 60, 60)));
        continue;
      }
      const auto it = matches.find({configs[std::size_t(config_of[std::size_t(c)])].row, p->file});
      std::string top = "no face", bottom;
      cv::Scalar colour(0, 0, 200);
      if (it != matches.end() && it->second.score > -1.5) {
        top = it->second.identity;
        char b[32];
        std::snprintf(b, sizeof b, "cosine %.3f", it->second.score);
        bottom = b;
        if (it->second.identity == p->identity) colour = cv::Scalar(0, 140, 0);
      }
      tiles.push_back(tile(images[std::size_t(c)], kSide, top, bottom, colour));
    }
    cv::Mat row;
    cv::hconcat(tiles, row);
    rows.push_back(row);
  }
  cv::Mat all;
  cv::vconcat(rows, all);
  write_image(fs::path(a.out) / "montage.png", image_from_bgr(all), true);
}

// "33.3 [0.0, 66.7]" from a results.json interval (percent or plain).
std::string cell(const ojson& x, double scale, const char* format, bool with_ci = true) {
  if (!x.contains("value") || x["value"].is_null()) return "—";
  const auto f = [&](double v) {
    char b[32];
    std::snprintf(b, sizeof b, format, scale * v);
    return std::string(b);
  };
  std::string s = f(x["value"].get<double>());
  if (with_ci && x.contains("ci95") && x["ci95"].is_array()) {
    const double lo = x["ci95"][0].get<double>(), hi = x["ci95"][1].get<double>();
    if (lo != hi) s += " [" + f(lo) + ", " + f(hi) + "]";
  }
  return s;
}

const ojson* find_row(const ojson& results, const std::string& method,
                      const std::string& strength) {
  for (const ojson& r : results["rows"]) {
    if (r["method"] == method && r["strength"] == strength) return &r;
  }
  return nullptr;
}

const ojson& at_key(const ojson& list, const char* key, double value) {
  for (const ojson& x : list) {
    if (std::abs(x[key].get<double>() - value) < 1e-12) return x;
  }
  static const ojson none = ojson::object();
  return none;
}

// The λ trade-off of a co-training study (scripts/cotrain_study's folder:
// its models and eval/results.json): for each evaluated restore-first model
// of all layers trained on paired clips with λ > 0, PSNR and the
// recognition at strong turbulence against λ, as lambda_psnr.png and
// lambda_recognition.png in `out`. Returns the λ values drawn (none when
// the folder holds no such study).
std::vector<double> write_lambda_plots(const fs::path& study, const fs::path& out) {
  const fs::path results_path = study / "eval" / "results.json";
  if (!fs::exists(results_path)) return {};
  std::ifstream in(results_path);
  const ojson results = ojson::parse(in, nullptr, false);
  if (!results.is_object() || !results.contains("rows")) {
    log_warn("demo: " + results_path.string() + " is not an evaluation's results.json: no λ plot");
    return {};
  }
  struct Point {
    double lambda, psnr, rank1, tar;
  };
  std::vector<Point> points;
  for (const ojson& r : results["rows"]) {
    const std::string method = r.value("method", "");
    if (r.value("strength", "") != "strong" || !method.starts_with("restored:")) continue;
    const fs::path model = study / (method.substr(9) + ".safetensors");
    if (!fs::exists(model)) continue;
    std::map<std::string, std::string> meta;
    try {
      meta = nets::read_safetensors(model).metadata;
    } catch (const Error&) {
      continue;
    }
    const auto get = [&](const char* k) {
      const auto it = meta.find(k);
      return it == meta.end() ? std::string() : it->second;
    };
    const double lambda = std::strtod(get("cotrain.lambda").c_str(), nullptr);
    if (!(lambda > 0) || get("cotrain.layers") != "all" ||
        get("cotrain.order") != "restore-first" || !get("cotrain.unpaired").empty()) {
      continue;
    }
    points.push_back({lambda, r["psnr_db"].value("value", std::nan("")),
                      100 * at_key(r["rank"], "rank", 1).value("value", std::nan("")),
                      100 * at_key(r["tar_at_far"], "far", 0.1).value("value", std::nan(""))});
  }
  if (points.size() < 2) return {};
  std::sort(points.begin(), points.end(),
            [](const Point& x, const Point& y) { return x.lambda < y.lambda; });
  PlotSpec psnr, rec;
  psnr.log_x = rec.log_x = true;
  psnr.x_label = rec.x_label = "λ (weight of the self-distillation)";
  psnr.x_min = rec.x_min = points.front().lambda / 1.5;
  psnr.x_max = rec.x_max = points.back().lambda * 1.5;
  psnr.title = "Restoration quality against λ (strong turbulence, " + study.string() + ")";
  psnr.y_label = "PSNR (dB)";
  rec.title = "Recognition against λ (strong turbulence, " + study.string() + ")";
  rec.y_label = "%";
  rec.y_min = 0;
  rec.y_max = 100;
  PlotSeries p{"PSNR", {}}, r1{"Rank-1", {}}, tar{"TAR at FAR 10 %", {}};
  double lo = 1e9, hi = -1e9;
  for (const Point& x : points) {
    p.points.emplace_back(x.lambda, x.psnr);
    r1.points.emplace_back(x.lambda, x.rank1);
    tar.points.emplace_back(x.lambda, x.tar);
    lo = std::min(lo, x.psnr);
    hi = std::max(hi, x.psnr);
  }
  psnr.y_min = std::floor(lo - 0.5);
  psnr.y_max = std::ceil(hi + 0.5);
  psnr.series = {p};
  rec.series = {r1, tar};
  rec.legend_top = true;
  write_plot(out / "lambda_psnr.png", psnr, true);
  write_plot(out / "lambda_recognition.png", rec, true);
  std::vector<double> lambdas;
  for (const Point& x : points) lambdas.push_back(x.lambda);
  return lambdas;
}

void run_jr2_demo(const Jr2DemoArgs& a) {
  const auto t0 = std::chrono::steady_clock::now();
  // Every artifact the study reads, before any work.
  for (const char* f :
       {"restorer_default.safetensors", "restorer_cotrained.safetensors", "gate.safetensors",
        "turbulence_estimator.safetensors", "p2s_default.safetensors"}) {
    if (!fs::exists(artifact(f))) {
      throw UsageError("demo", "the shipped artifact " + artifact(f).string() + " is missing",
                       "check out the repository's artifacts/ (or set VKJR2_ARTIFACT_DIR)");
    }
  }
  const fs::path out(a.out);
  check_output_folder(out, "--out");
  for (const char* f : {"report.md", "results.json", "montage.png", "restored_probe.avi"}) {
    if (fs::exists(out / f)) check_output_file(out / f, a.force, "--out");
  }
  create_output_folder(out, "--out");
  const fs::path bench = out / "bench", eval = out / "eval";
  const std::vector<Config> configs = {
      {"degraded", "degraded", "degraded"},
      {"+ restoration", "restored", "restored:restorer_default"},
      {"+ gate", "gated", "gated:restorer_default,gate"},
      {"+ co-optimization", "restored:" + artifact("restorer_cotrained.safetensors").string(),
       "restored:restorer_cotrained"}};
  std::string methods;
  for (const Config& c : configs) methods += (methods.empty() ? "" : ",") + c.method;
  const std::vector<std::string> quiet =
      a.quiet ? std::vector<std::string>{"--quiet"} : std::vector<std::string>{};
  const auto with = [&](std::vector<std::string> v) {
    v.insert(v.end(), quiet.begin(), quiet.end());
    if (!a.device.empty()) v.insert(v.end(), {"--device", a.device});
    return v;
  };
  const auto note = [&](const std::string& s) {
    if (!a.quiet) std::fprintf(stderr, "demo: %s\n", s.c_str());
  };
  std::map<std::string, double> step_seconds;
  auto t = std::chrono::steady_clock::now();
  note("1/4 the benchmark (" + std::to_string(a.identities) +
       " identities of face-api's photos, "
       "3 strengths, " +
       std::to_string(a.frames) + "-frame probe videos) in " + bench.string());
  run_step("benchmark",
           with({"dataset", "make", "--out", bench.string(), "--max-identities",
                 std::to_string(a.identities), "--frames", std::to_string(a.frames), "--clip-size",
                 std::to_string(a.clip), "--face-px", std::to_string(a.face_px), "--seed",
                 std::to_string(a.seed), "--resume"}));
  step_seconds["benchmark"] = seconds_since(t);
  t = std::chrono::steady_clock::now();
  note("2/4 the evaluation of the test split: " + methods);
  run_step("evaluation",
           with({"eval", (bench / "manifest.json").string(), "--out", eval.string(), "--split",
                 "test", "--align", "similarity", "--method", methods, "--resamples",
                 std::to_string(a.resamples), "--seed", std::to_string(a.seed), "--force"}));
  step_seconds["evaluation"] = seconds_since(t);
  const jr2::Manifest m = jr2::read_manifest(bench / "manifest.json");
  t = std::chrono::steady_clock::now();
  note("3/4 a restored video of one probe");
  const jr2::ProbeItem* video = nullptr;
  for (const auto& p : m.probes) {
    if (p.split == "test" && p.strength == "strong" && video == nullptr) video = &p;
  }
  if (video != nullptr) {
    run_step("restored video", with({"restore", (bench / video->file).string(),
                                     (out / "restored_probe.avi").string(), "--force"}));
  }
  step_seconds["restored_video"] = seconds_since(t);
  t = std::chrono::steady_clock::now();
  note("4/4 the montage and the report");
  write_montage(a, bench, m, configs, eval / "scores.csv");
  const std::vector<double> lambdas = write_lambda_plots(a.cotrain_study, out);
  step_seconds["montage"] = seconds_since(t);

  std::ifstream rin(eval / "results.json");
  const ojson results = ojson::parse(rin);
  std::ostringstream table;
  table
      << "| strength | configuration | TAR@FAR 10⁻¹ | Rank-1 | Rank-5 | FNIR@FPIR 10⁻¹ | PSNR dB | "
         "SSIM | skipped | s / probe |\n|---|---|---|---|---|---|---|---|---|---|\n";
  ojson summary = ojson::array();
  for (const char* strength : {"weak", "moderate", "strong"}) {
    for (const Config& c : configs) {
      const ojson* r = find_row(results, c.row, strength);
      if (r == nullptr) continue;
      const ojson& tar = at_key((*r)["tar_at_far"], "far", 0.1);
      const ojson& fnir = at_key((*r)["fnir_at_fpir"], "fpir", 0.1);
      const ojson& r1 = at_key((*r)["rank"], "rank", 1);
      const ojson& r5 = at_key((*r)["rank"], "rank", 5);
      const std::string skipped =
          r->contains("gate")
              ? cell({{"value", (*r)["gate"]["skipped_share"]}}, 100, "%.0f %%", false)
              : "—";
      table << "| " << strength << " | " << c.label << " | "
            << (tar.value("reported", false) ? cell(tar, 100, "%.1f") : "n/a") << " | "
            << (r1.value("trivial", false) ? "n/a" : cell(r1, 100, "%.1f")) << " | "
            << (r5.value("trivial", false) ? "n/a" : cell(r5, 100, "%.1f")) << " | "
            << (fnir.value("reported", false) ? cell(fnir, 100, "%.1f") : "n/a") << " | "
            << cell((*r)["psnr_db"], 1, "%.2f", false) << " | "
            << cell((*r)["ssim"], 1, "%.3f", false) << " | " << skipped << " | "
            << cell((*r)["seconds_per_probe"], 1, "%.2f", false) << " |\n";
      summary.push_back({{"strength", strength},
                         {"configuration", c.label},
                         {"method", c.row},
                         {"tar_at_far_0.1", tar},
                         {"rank1", r1},
                         {"rank5", r5},
                         {"fnir_at_fpir_0.1", fnir},
                         {"psnr_db", (*r)["psnr_db"]},
                         {"ssim", (*r)["ssim"]},
                         {"seconds_per_probe", (*r)["seconds_per_probe"]},
                         {"gate", r->value("gate", ojson())}});
    }
  }
  // Two sentences from the numbers.
  const auto value = [&](const std::string& method, const char* strength, double rank) {
    const ojson* r = find_row(results, method, strength);
    return r == nullptr ? std::nan("")
                        : at_key((*r)["rank"], "rank", rank).value("value", std::nan(""));
  };
  const ojson* gated_all = nullptr;
  double skipped = 0, probes = 0, t_gate = 0, t_all = 0;
  for (const char* strength : {"weak", "moderate", "strong"}) {
    if ((gated_all = find_row(results, configs[2].row, strength)) != nullptr) {
      const double n = (*gated_all)["probes"].get<double>();
      probes += n;
      skipped += n * (*gated_all)["gate"]["skipped_share"].get<double>();
      t_gate += n * (*gated_all)["seconds_per_probe"]["value"].get<double>();
    }
    if (const ojson* r = find_row(results, configs[1].row, strength)) {
      t_all += (*r)["probes"].get<double>() * (*r)["seconds_per_probe"]["value"].get<double>();
    }
  }
  char says[1024];
  std::snprintf(says, sizeof says,
                "At strong turbulence the mate is first for %.0f %% of the mated probes degraded, "
                "%.0f %% restored, %.0f %% with the gate and %.0f %% co-optimized; with this many "
                "probes the intervals overlap, so read the direction, not the size. The gate left "
                "%.0f %% of all probes unrestored and took %.0f %% of restore-all's time.",
                100 * value(configs[0].row, "strong", 1), 100 * value(configs[1].row, "strong", 1),
                100 * value(configs[2].row, "strong", 1), 100 * value(configs[3].row, "strong", 1),
                probes > 0 ? 100 * skipped / probes : std::nan(""),
                t_all > 0 ? 100 * t_gate / t_all : std::nan(""));
  const double seconds = seconds_since(t0);
  std::ostringstream md;
  md << "# JR²: restoring for recognition, with the shipped artifacts\n\n"
     << "What was run: `vkjr2 demo` made a benchmark of " << m.identities
     << " identities (face-api's sample photos, " << m.probes.size() << " probe videos of "
     << a.frames << " frames at weak, moderate and strong turbulence; `bench/`), then evaluated "
     << "its test split (`eval/`) four ways: the degraded probes; every probe restored by the "
        "shipped restorer; the shipped gate deciding per probe whether to restore; every probe "
        "restored by the co-optimized restorer. Device: "
     << results["setup"]["device"].get<std::string>() << "; " << std::lround(seconds) << " s.\n\n"
     << table.str() << "\nPercentages with bootstrap 95 % intervals (identities, then probes). "
     << says
     << "\n\nPictures: `montage.png` (clean | degraded | restored | co-optimized, each "
        "face labelled with its top gallery match and cosine; green: the right identity), "
        "`eval/roc.png`, `eval/cmc.png`, `eval/fnir_fpir.png`, `eval/rank_change.png`; a "
        "restored probe video: `restored_probe.avi`. ";
  if (lambdas.empty()) {
    md << "No λ trade-off plot: " << a.cotrain_study
       << " holds no evaluated co-training study (`scripts/cotrain_study " << a.cotrain_study
       << "` makes one, in about an hour a model). ";
  } else {
    md << "The λ trade-off of the co-training study in " << a.cotrain_study << " (λ =";
    for (double l : lambdas) md << " " << l;
    md << "): `lambda_psnr.png`, `lambda_recognition.png`. ";
  }
  md << "The full study on the whole benchmark, beside the seed paper's numbers, is docs/jr2.md "
        "§5 and §8.\n";
  const std::string report = md.str();
  const ojson j{{"identities", m.identities},
                {"probes", m.probes.size()},
                {"frames", a.frames},
                {"seconds", seconds},
                {"step_seconds", step_seconds},
                {"table", summary},
                {"says", says},
                {"evaluation", (eval / "results.json").string()},
                {"lambda_plot", lambdas}};
  const std::string jtext = j.dump(1) + "\n";
  write_file_atomic(out / "results.json", std::as_bytes(std::span(jtext)), "demo");
  write_file_atomic(out / "report.md", std::as_bytes(std::span(report)), "demo");
  if (a.json_out) {
    std::printf("%s", jtext.c_str());
  } else {
    std::printf(
        "%s\nwrote %s/{report.md, results.json, montage.png, restored_probe.avi, eval/, "
        "bench/} in %.0f s\n",
        report.c_str(), out.string().c_str(), seconds);
  }
}

}  // namespace

void add_demo(CLI::App& app) {
  auto a = std::make_shared<Jr2DemoArgs>();
  CLI::App* cmd = app.add_subcommand(
      "demo",
      "The JR² study with the shipped artifacts: degraded / restored / gated / co-optimized");
  cmd->footer(
      "Makes a small benchmark of face-api's sample photos (vkjr2 dataset make, kept and reused "
      "in OUT/bench),\n"
      "evaluates its test split (vkjr2 eval) four ways — degraded; + restoration (the shipped "
      "restorer on\n"
      "every probe); + gate (the shipped gate decides per probe); + co-optimization (the "
      "co-optimized restorer)\n"
      "— and writes report.md (the summary table per strength: TAR@FAR, Rank-1/5, FNIR@FPIR, "
      "PSNR, SSIM,\n"
      "skip rate, time per probe, with 95 % intervals), results.json, montage.png, "
      "restored_probe.avi and the\n"
      "evaluation's plots in OUT/eval; with an evaluated co-training study in --cotrain-study, "
      "its λ trade-off\n"
      "(lambda_psnr.png, lambda_recognition.png). The study on the whole benchmark is "
      "docs/jr2.md.\n"
      "Example:\n  vkjr2 demo --out out/demo --force\n"
      "The turbulence-vs-recognition study on the sample photos and vtest.avi: vkjr2 "
      "demo-turbulence.");
  cmd->add_option("--out", a->out, "Output folder")->default_val("out/demo");
  cmd->add_option("--identities", a->identities, "Identities of the benchmark (its size and time)")
      ->default_val(a->identities)
      ->check(integer_range(2, 100000));
  cmd->add_option("--frames", a->frames, "Frames per probe video")
      ->default_val(a->frames)
      ->check(integer_range(8, 1000));
  cmd->add_option("--clip-size", a->clip, "Side of the clips (px)")
      ->default_val(a->clip)
      ->check(integer_range(32, 1024));
  cmd->add_option("--face-px", a->face_px, "Width of the face in a clip (px)")
      ->default_val(a->face_px)
      ->check(integer_range(8, 1024));
  cmd->add_option("--montage", a->montage, "Probes in montage.png")
      ->default_val(a->montage)
      ->check(integer_range(1, 50));
  cmd->add_option("--cotrain-study", a->cotrain_study,
                  "A co-training study's folder (scripts/cotrain_study): when it holds an "
                  "evaluated λ sweep, its trade-off is plotted")
      ->default_val(a->cotrain_study);
  cmd->add_option("--resamples", a->resamples, "Bootstrap resamples of each interval")
      ->default_val(a->resamples)
      ->check(integer_range(10, 100000));
  add_seed_option(cmd, a->seed, "Seed of the benchmark, the sampler and the bootstrap");
  cmd->add_option("--device", a->device,
                  "Vulkan device index or name substring (else VKJR2_DEVICE)");
  cmd->add_flag("--json", a->json_out, "Print results.json instead of the report");
  cmd->add_flag("--quiet", a->quiet, "No progress bars");
  cmd->add_flag("--force", a->force, "Replace existing output files");
  cmd->callback([a] { run_jr2_demo(*a); });
}

}  // namespace vkjr2::cli
