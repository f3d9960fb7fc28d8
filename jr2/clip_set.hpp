// Cached clip sets for scoring restorers on a fixed test domain
// (docs/restoration.md, study 2): T degraded frames and the clean frame of
// each clip, in one safetensors file. `make_wave_clips` degrades clean crops
// through the split-step wave-optics reference (sim/wave_image.hpp), a
// domain none of the restorers trains on; `score_clip_set` scores the
// reference frame of every clip as degraded, restored by the classical peer
// and restored by each network, with bootstrap intervals over the clips.
#pragma once

#include <vkjr2/jr2/metrics.hpp>
#include <vkjr2/jr2/restore_train.hpp>
#include <vkjr2/jr2/restorer.hpp>
#include <vkjr2/sim/wave_image.hpp>

#include <cstdint>
#include <filesystem>
#include <functional>
#include <map>
#include <string>
#include <vector>

namespace vkjr2::jr2 {

struct ClipSet {
  int frames = 0;  // T
  int size = 0;    // S: clips are S² pixels
  // [N, T, 3, S, S] degraded frames and [N, 3, S, S] clean frames, 0..1.
  std::vector<float> degraded, clean;
  std::vector<double> d_over_r0;     // per clip
  std::vector<std::string> sources;  // per clip: the clean image's name
  std::map<std::string, std::string> metadata;
  std::size_t count() const noexcept { return d_over_r0.size(); }
};

struct WaveClipOptions {
  int clips = 12, frames = 8, size = 64;
  double d_over_r0_lo = 1, d_over_r0_hi = 8;  // clip i: log-spaced over the range
  std::uint64_t seed = 1;
  // Frozen flow: > 0 images a clip's frames through one set of screens,
  // displaced by this many metres per frame in a direction drawn per clip
  // (0.04 = 0.2 D gives the presets' tilt correlation ≈ 0.9 between frames);
  // 0: every frame through its own independent screens.
  double screen_motion_m = 0;
  sim::WaveImageConfig wave;
  // Throws InvalidArgument naming the option and the fix.
  void validate() const;
};

// Clip i: a centre crop (half the shorter side, at least S) of image
// i mod images.size() resampled to S², imaged T times through the
// wave-optics reference, each frame through its own independent screens
// (seed from (seed, i, t)) or, with screen_motion_m, through the clip's
// screens moving between frames. The optics are RestoreTrainer's
// (probe_sim_params). progress(done, total) counts frames.
ClipSet make_wave_clips(const Device& device, const std::vector<TrainImage>& images,
                        const WaveClipOptions& options,
                        const std::function<void(int, int)>& progress = {});

// Atomic write; the reader checks every tensor's shape and names the file.
void save_clip_set(const std::filesystem::path& path, const ClipSet& set);
ClipSet load_clip_set(const std::filesystem::path& path);

struct MethodScore {
  std::string method;
  std::vector<double> psnr, ssim;  // per clip
  Interval psnr_mean, ssim_mean;   // over the clips
  Interval psnr_gain;              // paired: method − degraded, in dB
};

// Rows: "degraded", "classical", then one per restorer (named by `names`).
// A restorer of T' frames reads the T' frames around the set's reference
// frame T / 2 (restore_window).
std::vector<MethodScore> score_clip_set(const Device& device, const ClipSet& set,
                                        const std::vector<const Restorer*>& restorers,
                                        const std::vector<std::string>& names,
                                        const ClassicalOptions& classical = {},
                                        const BootstrapOptions& bootstrap = {});

}  // namespace vkjr2::jr2
