#include "probe_run.hpp"

#include <vkjr2/jr2/align.hpp>
#include <vkjr2/jr2/metrics.hpp>
#include <vkjr2/nets/autograd.hpp>
#include <vkjr2/nets/face_common.hpp>
#include <vkjr2/nets/safetensors.hpp>
#include <vkjr2/runtime/error.hpp>
#include <vkjr2/runtime/image.hpp>
#include <vkjr2/sim/params.hpp>

#include <algorithm>
#include <chrono>
#include <cmath>

#include "checks.hpp"
#include "registration.hpp"

namespace vkjr2::cli {
namespace {

namespace fs = std::filesystem;

// Frames the classical peer averages (the restorer's default T).
constexpr int kClassicalFrames = 8;

double seconds_since(std::chrono::steady_clock::time_point t0) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
}

const char* const kMethodFix =
    "use degraded, classical, restored (the shipped restorer), restored:MODEL.safetensors or "
    "gated:MODEL.safetensors,GATE.safetensors (gated:restored,gated for the shipped ones)";

fs::path shipped_gate_path() {
  return jr2::default_restorer_path().parent_path() / "gate.safetensors";
}

// A model argument: "restored" names the shipped restorer.
fs::path restorer_file(const std::string& text) {
  return text == "restored" ? jr2::default_restorer_path() : fs::path(text);
}

fs::path gate_file(const std::string& text) {
  return text == "gated" ? shipped_gate_path() : fs::path(text);
}

// gated:MODEL,GATE → {MODEL, GATE}.
std::pair<fs::path, fs::path> gated_files(const std::string& text) {
  const std::string rest = text.substr(6);
  const std::size_t comma = rest.find(',');
  if (comma == std::string::npos || comma == 0 || comma + 1 == rest.size()) {
    throw UsageError("--method", "'" + text + "' does not name a restorer and a gate",
                     "write gated:MODEL.safetensors,GATE.safetensors (a restorer, then the "
                     "gate `vkjr2 gate train` wrote)");
  }
  return {restorer_file(rest.substr(0, comma)), gate_file(rest.substr(comma + 1))};
}

}  // namespace

std::vector<fs::path> check_method(const std::string& text) {
  if (text == "degraded" || text == "classical") return {};
  if (text == "restored") {
    check_input_file(jr2::default_restorer_path(), "--method restored (the shipped restorer)");
    return {jr2::default_restorer_path()};
  }
  if (text.rfind("restored:", 0) == 0 && text.size() > 9) {
    fs::path model = text.substr(9);
    check_input_file(model, "--method " + text);
    return {model};
  }
  if (text.rfind("gated:", 0) == 0) {
    const auto [model, gate] = gated_files(text);
    check_input_file(model, "--method " + text + " (its restorer)");
    check_input_file(gate, "--method " + text + " (its gate)");
    return {model, gate};
  }
  if (text == "gated") return check_method("gated:restored,gated");
  throw UsageError("--method", "unknown method '" + text + "'", kMethodFix);
}

Method load_method(const Device& device, const std::string& text) {
  Method m;
  m.name = text;
  m.classical = text == "classical";
  const std::vector<fs::path> files = check_method(text);
  if (files.empty()) return m;
  m.restorer = jr2::Restorer::load(device, files[0]);
  m.name = "restored:" + files[0].stem().string();
  const auto meta = nets::read_safetensors(files[0]).metadata;
  const auto order = meta.find("cotrain.order");
  m.align_first = order != meta.end() && order->second == "align-first";
  if (files.size() == 2) {
    if (m.align_first) {
      throw UsageError("--method " + text, "the gate runs before restoration of whole frames",
                       "gate a restore-first model");
    }
    m.gate = std::make_unique<jr2::Gate>(jr2::Gate::load(device, files[1]));
    m.name = "gated:" + files[0].stem().string() + "," + files[1].stem().string();
  }
  return m;
}

GateContext gate_context(const jr2::ProtocolOptions& protocol, jr2::AlignMode align) {
  GateContext g;
  g.optics = sim::preset("moderate");
  const fs::path cal = jr2::default_turbulence_calibration_path();
  check_input_file(cal, "the shipped turbulence calibration");
  g.calibration = jr2::TurbulenceCalibration::load(cal);
  if (g.calibration.registration != "dis") {
    throw Error("gate",
                cal.string() + " was fitted with registration " + g.calibration.registration,
                "ship a calibration fitted with DIS (vkjr2 estimate-train)");
  }
  const auto it = std::find(protocol.aligns.begin(), protocol.aligns.end(), align);
  if (it == protocol.aligns.end()) {
    throw UsageError("--align",
                     std::string("the gate reads the ") + jr2::align_mode_name(align) +
                         " alignment's template, which is not evaluated",
                     std::string("add ") + jr2::align_mode_name(align) + " to --align");
  }
  g.align_index = int(it - protocol.aligns.begin());
  return g;
}

ProbeVideo::ProbeVideo(const Device& device, std::vector<HostTensor> frames, Tensor clean,
                       fs::path clean_path, std::uint64_t sampler_seed)
    : device_(device),
      frames_(std::move(frames)),
      unit_(frames_.size()),
      clean_(std::move(clean)),
      clean_path_(std::move(clean_path)),
      seed_(sampler_seed) {
  if (frames_.empty()) {
    throw InvalidArgument("probe video", "no frames", "give a video with frames");
  }
}

const Tensor& ProbeVideo::unit_frame(std::size_t i) {
  if (!unit_[i].defined()) unit_[i] = image_to_device(device_, frames_[i], 3, 255.f);
  return unit_[i];
}

double ProbeVideo::d_over_r0(const GateContext& g) {
  if (d_over_r0_) return *d_over_r0_;
  const int t = int(frames_.size()), h = int(frames_[0].shape[0]), w = int(frames_[0].shape[1]);
  std::vector<float> grey;
  grey.reserve(std::size_t(t) * h * w);
  for (const HostTensor& f : frames_) {
    const std::vector<float> plane = image_to_planes(f, 1, 255.f);
    grey.insert(grey.end(), plane.begin(), plane.end());
  }
  d_over_r0_ = estimate_grey_video(device_, grey, t, h, w, g.optics, g.calibration).d_over_r0;
  return *d_over_r0_;
}

jr2::GateFeatures gate_features(ProbeContext& ctx, ProbeVideo& video,
                                const jr2::ProbeOutcome& degraded) {
  if (ctx.gate == nullptr) throw Error("gate features", "no gate context", "internal error");
  const int al = ctx.gate->align_index;
  jr2::GateFeatures f;
  f.acquired = !degraded.templates[std::size_t(al)].empty();
  f.descriptor = degraded.templates[std::size_t(al)];
  double norm = 0, score = 0;
  int tracked = 0;
  for (const auto& d : degraded.descriptors[std::size_t(al)]) {
    double s = 0;
    for (float v : d) s += double(v) * v;
    norm += std::sqrt(s);
  }
  if (!degraded.descriptors[std::size_t(al)].empty()) {
    norm /= double(degraded.descriptors[std::size_t(al)].size());
  }
  double sharp = 0;
  for (const jr2::FrameOutcome& fo : degraded.frames) {
    const HostTensor& img = video.frames()[std::size_t(fo.frame)];
    const int h = int(img.shape[0]), w = int(img.shape[1]);
    int x0 = w / 4, y0 = h / 4, x1 = w - w / 4, y1 = h - h / 4;  // the clip's centre
    if (fo.tracked) {
      ++tracked;
      score += fo.score;
      x0 = int(std::floor(fo.box.x));
      y0 = int(std::floor(fo.box.y));
      x1 = int(std::ceil(fo.box.x + fo.box.width));
      y1 = int(std::ceil(fo.box.y + fo.box.height));
    }
    sharp += jr2::gate_sharpness(image_to_planes(img, 1, 255.f), h, w, x0, y0, x1, y1);
  }
  f.descriptor_norm = norm;
  f.detector_score = tracked > 0 ? score / tracked : 0;
  f.tracked_share = degraded.frames.empty() ? 0 : double(tracked) / double(degraded.frames.size());
  f.sharpness = degraded.frames.empty() ? 0 : sharp / double(degraded.frames.size());
  f.d_over_r0 = video.d_over_r0(*ctx.gate);
  return f;
}

namespace {

MethodRun run_plain(ProbeContext& ctx, const Method& method, ProbeVideo& video) {
  const auto t0 = std::chrono::steady_clock::now();
  Stream& stream = ctx.stream;
  const Device& device = ctx.device;
  const auto& frames = video.frames();
  const bool restores = (method.restorer || method.classical) && !method.align_first;
  // degraded: the frames as the camera gave them; classical and restored:
  // each sampled frame made from the T around it. The frames are made once:
  // the pipeline asks for them, the image quality reads them again.
  std::vector<Tensor> sampled;
  const auto frame = [&](int f) {
    if (!restores) {
      sampled.push_back(image_to_device(device, frames[std::size_t(f)]));
      return sampled.back();
    }
    const int t = method.restorer ? method.restorer->config().frames : kClassicalFrames;
    std::vector<Tensor> window;
    for (std::size_t i : jr2::restore_window(frames.size(), std::size_t(f), t)) {
      window.push_back(video.unit_frame(i));
    }
    Tensor unit;  // 0..1
    if (method.restorer) {
      nets::Tape tape(stream, false);
      unit = method.restorer->forward(tape, nets::Var(jr2::stack_frames(stream, window))).value();
    } else {
      unit = jr2::classical_restore(stream, window, ctx.classical);
    }
    // The pipeline and the quality take 0..255 pixels, clamped as a saved frame is.
    sampled.push_back(jr2::to_pixels(stream, unit));
    return sampled.back();
  };
  // Align-first: the tracked faces' crops are the window's frames aligned by
  // the frame's similarity and restored; their quality is against the clean
  // clip aligned the same way.
  std::vector<jr2::ClipQuality> crop_quality;
  const auto aligned_crop = [&](Stream& s, int f, const jr2::Similarity& sim) {
    const jr2::Restorer& net = *method.restorer;
    std::vector<Tensor> window;
    for (std::size_t i : jr2::restore_window(frames.size(), std::size_t(f), net.config().frames)) {
      window.push_back(video.unit_frame(i));
    }
    const int c = int(nets::kRecognitionInputSize);
    nets::Tape tape(s, false);
    const nets::Var in = jr2::align_crop(tape, nets::Var(jr2::stack_frames(s, window)), sim, c);
    Tensor crop = jr2::to_pixels(s, net.forward(tape, in).value());
    const Tensor clean_crop = jr2::align_crop(tape, nets::Var(video.clean()), sim, c).value();
    crop_quality.push_back(jr2::clip_quality(s, std::span(&crop, 1), clean_crop));
    return crop;
  };
  MethodRun run;
  if (method.align_first) {
    jr2::ProtocolOptions with_crops = ctx.pipeline.options();
    with_crops.aligned_crop = aligned_crop;
    run.outcome = jr2::ProbePipeline(ctx.analyzer, with_crops)
                      .run(stream, int(frames.size()), frame, video.sampler_seed());
  } else {
    run.outcome = ctx.pipeline.run(stream, int(frames.size()), frame, video.sampler_seed());
  }
  // Image quality of the same sampled frames against the clean clip.
  if (!(sampled.front().shape() == video.clean().shape())) {
    throw Error("eval",
                video.clean_path().string() + " is " + video.clean().shape().str() +
                    ", its probe has frames of " + sampled.front().shape().str(),
                "make the benchmark again (vkjr2 dataset make)");
  }
  if (!method.align_first) {
    run.quality = jr2::clip_quality(stream, sampled, video.clean());
  } else {
    run.quality = {std::nan(""), std::nan("")};  // no face tracked: no crop restored
    if (!crop_quality.empty()) {
      run.quality = {0, 0};
      for (const auto& q : crop_quality) {
        run.quality.psnr_db += q.psnr_db / double(crop_quality.size());
        run.quality.ssim += q.ssim / double(crop_quality.size());
      }
    }
  }
  run.seconds = seconds_since(t0);
  return run;
}

}  // namespace

MethodRun run_method(ProbeContext& ctx, const Method& method, ProbeVideo& video) {
  if (!method.gate) return run_plain(ctx, method, video);
  const auto t0 = std::chrono::steady_clock::now();
  const Method degraded{.name = "degraded"};
  MethodRun run = run_plain(ctx, degraded, video);
  const jr2::GateFeatures f = gate_features(ctx, video, run.outcome);
  run.gate = method.gate->predict(ctx.stream, f);
  if (run.gate->restore) {
    // run_plain restores with the method's restorer (it does not read the gate).
    MethodRun r = run_plain(ctx, method, video);
    r.gate = run.gate;
    run = std::move(r);
  }
  run.seconds = seconds_since(t0);
  return run;
}

}  // namespace vkjr2::cli
