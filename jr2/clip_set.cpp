#include <vkjr2/jr2/benchmark.hpp>
#include <vkjr2/jr2/clip_set.hpp>
#include <vkjr2/kernels/metrics.hpp>
#include <vkjr2/nets/safetensors.hpp>
#include <vkjr2/runtime/error.hpp>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <numbers>
#include <numeric>

#include "internal/text_and_draws.hpp"

namespace vkjr2::jr2 {
namespace {

constexpr const char* kFormat = "vkjr2-clip-set-1";

void require(bool ok, const std::string& what, const std::string& fix) {
  if (!ok) throw InvalidArgument("wave clips", what, fix);
}

std::string num(double x) { return detail::number_text(x, 9); }

double mean_of(std::span<const double> v, std::span<const std::size_t> idx) {
  double a = 0;
  for (std::size_t i : idx) a += v[i];
  return idx.empty() ? std::nan("") : a / double(idx.size());
}

}  // namespace

void WaveClipOptions::validate() const {
  require(clips >= 1 && clips <= 10000, "--clips " + std::to_string(clips), "use 1..10000 clips");
  require(frames >= 1 && frames <= 64, "--frames " + std::to_string(frames), "use 1..64 frames");
  require(size >= 16 && size <= 512, "--size " + std::to_string(size), "use 16..512 pixels");
  require(d_over_r0_lo > 0 && d_over_r0_hi >= d_over_r0_lo && d_over_r0_hi <= 20,
          "D/r0 range [" + num(d_over_r0_lo) + ", " + num(d_over_r0_hi) + "]",
          "use 0 < lo <= hi <= 20");
  require(std::isfinite(screen_motion_m) && screen_motion_m >= 0 && screen_motion_m <= 10,
          "--screen-motion " + num(screen_motion_m),
          "use 0..10 metres per frame (0.04 = a fifth of the aperture; 0: independent frames)");
}

ClipSet make_wave_clips(const Device& device, const std::vector<TrainImage>& images,
                        const WaveClipOptions& o, const std::function<void(int, int)>& progress) {
  o.validate();
  require(!images.empty(), "no clean images", "pass at least one image");
  for (const TrainImage& im : images) {
    const auto& s = im.rgb.shape;
    require(s.size() == 3 && s[2] == 3 && s[0] >= o.size && s[1] >= o.size,
            im.name + " has shape " + shape_str(s),
            "pass H×W×3 RGB images of at least " + std::to_string(o.size) + "² pixels");
  }
  ClipSet set;
  set.frames = o.frames;
  set.size = o.size;
  const std::size_t px = std::size_t(o.size) * std::size_t(o.size);
  const std::size_t frame_size = 3 * px;
  set.degraded.resize(std::size_t(o.clips) * std::size_t(o.frames) * frame_size);
  set.clean.resize(std::size_t(o.clips) * frame_size);
  int done = 0;
  for (int i = 0; i < o.clips; ++i) {
    const TrainImage& img = images[std::size_t(i) % images.size()];
    const std::vector<float> clean = held_out_crop(img.rgb, o.size);
    std::copy(clean.begin(), clean.end(), set.clean.begin() + std::ptrdiff_t(i * frame_size));
    const double u = o.clips > 1 ? double(i) / double(o.clips - 1) : 0.5;
    const double d = o.d_over_r0_lo * std::pow(o.d_over_r0_hi / o.d_over_r0_lo, u);
    const sim::Params p = probe_sim_params(d, o.size);
    // The clip's screens (frozen flow) or frame t's own (seed state + t + 1).
    const std::uint64_t state = o.seed * detail::kGoldenGamma + std::uint64_t(i) * 1000003ULL;
    const std::uint64_t clip_seed = detail::splitmix_finalize(state);
    const double direction =
        2 * std::numbers::pi * detail::unit_interval(detail::splitmix_finalize(clip_seed + 1));
    for (int t = 0; t < o.frames; ++t) {
      sim::WaveImageConfig config = o.wave;
      if (o.screen_motion_m > 0) {
        config.wave.seed = clip_seed;
        config.wave.screen_offset_m = {t * o.screen_motion_m * std::cos(direction),
                                       t * o.screen_motion_m * std::sin(direction)};
      } else {
        config.wave.seed = detail::splitmix_finalize(state + std::uint64_t(t) + 1);
      }
      const std::vector<float> y = sim::wave_image(device, p, config, clean);
      float* dst = set.degraded.data() +
                   (std::size_t(i) * std::size_t(o.frames) + std::size_t(t)) * frame_size;
      for (std::size_t k = 0; k < frame_size; ++k) dst[k] = std::clamp(y[k], 0.f, 1.f);
      if (progress) progress(++done, o.clips * o.frames);
    }
    set.d_over_r0.push_back(d);
    set.sources.push_back(img.name);
  }
  set.metadata = {{"source", "wave-optics"},
                  {"clips", std::to_string(o.clips)},
                  {"frames", std::to_string(o.frames)},
                  {"size", std::to_string(o.size)},
                  {"d_over_r0", num(o.d_over_r0_lo) + "," + num(o.d_over_r0_hi)},
                  {"seed", std::to_string(o.seed)},
                  {"screen_motion_m", num(o.screen_motion_m)},
                  {"wave.grid", std::to_string(o.wave.wave.grid)},
                  {"wave.screens", std::to_string(o.wave.wave.screens)},
                  {"wave.source_step_px", num(o.wave.source_step_px)}};
  return set;
}

void save_clip_set(const std::filesystem::path& path, const ClipSet& set) {
  const auto n = std::int64_t(set.count());
  const std::int64_t t = set.frames, s = set.size;
  if (set.degraded.size() != std::size_t(n * t * 3 * s * s) ||
      set.clean.size() != std::size_t(n * 3 * s * s) || set.sources.size() != set.count()) {
    throw InvalidArgument("save_clip_set", "the set's arrays do not fit its count and shape",
                          "make the set with make_wave_clips");
  }
  std::vector<float> d(set.d_over_r0.begin(), set.d_over_r0.end());
  const std::vector<nets::SafetensorsRecord> records = {
      nets::SafetensorsRecord::f32("degraded", {n, t, 3, s, s}, set.degraded),
      nets::SafetensorsRecord::f32("clean", {n, 3, s, s}, set.clean),
      nets::SafetensorsRecord::f32("d_over_r0", {n}, d)};
  std::map<std::string, std::string> meta = set.metadata;
  meta["format"] = kFormat;
  std::string names;
  for (const std::string& src : set.sources) names += (names.empty() ? "" : "\n") + src;
  meta["sources"] = names;
  nets::write_safetensors(path, records, meta);
}

ClipSet load_clip_set(const std::filesystem::path& path) {
  const nets::SafetensorsFile f = nets::read_safetensors(path);
  const std::string where = path.string();
  const auto format = f.metadata.find("format");
  if (format == f.metadata.end() || format->second != kFormat) {
    throw InvalidArgument("clip set",
                          where + " is not a clip set (format " +
                              (format == f.metadata.end() ? "none" : format->second) + ")",
                          "make one with vkjr2 wave-clips");
  }
  const nets::SafetensorsRecord& deg = f.at("degraded");
  const nets::SafetensorsRecord& clean = f.at("clean");
  const nets::SafetensorsRecord& d = f.at("d_over_r0");
  const auto& ds = deg.shape;
  if (ds.size() != 5 || ds[2] != 3 || ds[3] != ds[4] || ds[0] < 1 || ds[1] < 1 ||
      clean.shape != std::vector<std::int64_t>{ds[0], 3, ds[3], ds[4]} ||
      d.shape != std::vector<std::int64_t>{ds[0]}) {
    throw InvalidArgument("clip set",
                          where + ": degraded " + shape_str(ds) + ", clean " +
                              shape_str(clean.shape) + ", d_over_r0 " + shape_str(d.shape) +
                              " do not fit [N, T, 3, S, S], [N, 3, S, S], [N]",
                          "remake the file with vkjr2 wave-clips");
  }
  ClipSet set;
  set.frames = int(ds[1]);
  set.size = int(ds[3]);
  set.degraded = deg.to_float();
  set.clean = clean.to_float();
  for (float x : d.to_float()) set.d_over_r0.push_back(double(x));
  set.metadata = f.metadata;
  const auto src = f.metadata.find("sources");
  std::string rest = src == f.metadata.end() ? std::string() : src->second;
  for (std::size_t i = 0; i < set.count(); ++i) {
    const std::size_t nl = rest.find('\n');
    set.sources.push_back(rest.substr(0, nl));
    rest = nl == std::string::npos ? std::string() : rest.substr(nl + 1);
  }
  return set;
}

std::vector<MethodScore> score_clip_set(const Device& device, const ClipSet& set,
                                        const std::vector<const Restorer*>& restorers,
                                        const std::vector<std::string>& names,
                                        const ClassicalOptions& classical,
                                        const BootstrapOptions& bootstrap) {
  if (names.size() != restorers.size()) {
    throw InvalidArgument("score_clip_set", "a name per restorer is needed",
                          "pass as many names as restorers");
  }
  const std::int64_t s = set.size;
  const Shape frame{1, 3, s, s};
  const std::size_t frame_size = std::size_t(3 * s * s);
  std::vector<MethodScore> rows(2 + restorers.size());
  rows[0].method = "degraded";
  rows[1].method = "classical";
  for (std::size_t r = 0; r < restorers.size(); ++r) rows[2 + r].method = names[r];
  Stream stream(device);
  const Tensor psnr = Tensor::empty(device, Shape{1}), ssim = Tensor::empty(device, Shape{1});
  const std::size_t reference = std::size_t(set.frames / 2);
  for (std::size_t i = 0; i < set.count(); ++i) {
    std::vector<Tensor> frames;
    for (int t = 0; t < set.frames; ++t) {
      const float* src =
          set.degraded.data() + (i * std::size_t(set.frames) + std::size_t(t)) * frame_size;
      frames.push_back(Tensor::from(device, frame, std::span<const float>(src, frame_size)));
    }
    const Tensor clean = Tensor::from(
        device, frame, std::span<const float>(set.clean.data() + i * frame_size, frame_size));
    auto score = [&](MethodScore& row, const Tensor& x) {
      kernels::psnr(stream, x, clean, 1.f, psnr);
      kernels::ssim(stream, x, clean, 1.f, ssim);
      stream.run();
      row.psnr.push_back(double(psnr.download()[0]));
      row.ssim.push_back(double(ssim.download()[0]));
    };
    score(rows[0], frames[reference]);
    score(rows[1], classical_restore(stream, frames, classical));
    for (std::size_t r = 0; r < restorers.size(); ++r) {
      std::vector<Tensor> window;
      for (std::size_t k :
           restore_window(frames.size(), reference, restorers[r]->config().frames)) {
        window.push_back(frames[k]);
      }
      nets::Tape tape(stream, false);
      const nets::Var out = restorers[r]->forward(tape, nets::Var(stack_frames(stream, window)));
      score(rows[2 + r], out.value());
    }
  }
  std::vector<int> unit(set.count());
  std::iota(unit.begin(), unit.end(), 0);
  for (MethodScore& row : rows) {
    auto of = [&](const std::vector<double>& v) {
      return bootstrap_items(
          unit, [&](std::span<const std::size_t> idx) { return mean_of(v, idx); }, bootstrap);
    };
    row.psnr_mean = of(row.psnr);
    row.ssim_mean = of(row.ssim);
    std::vector<double> gain(row.psnr.size());
    for (std::size_t i = 0; i < gain.size(); ++i) gain[i] = row.psnr[i] - rows[0].psnr[i];
    row.psnr_gain = of(gain);
  }
  return rows;
}

}  // namespace vkjr2::jr2
