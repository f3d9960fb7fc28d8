// The JR² restorer: a light NAFNet-style U-Net (Chen et al., ECCV 2022) that
// restores the reference frame of a short turbulent clip (docs/restoration.md).
//
// Input: T RGB frames stacked on the channels, [N, 3T, H, W] in [0, 1]
// (frame f is channels 3f..3f+2; early fusion). Output: the restored
// reference frame r = T / 2, [N, 3, H, W], predicted as a residual on that
// frame. Any H and W: the input is zero-padded to a multiple of 2^levels on
// the bottom and right and the output cropped back.
//
//   intro 3×3 (3T → w) → L × [NAFBlocks at width c_i = w·2^i, 2×2 stride-2
//   conv → 2c_i] → middle NAFBlocks at c_L → L × [1×1 conv c → 2c, pixel
//   shuffle 2 → c/2, + the skip, NAFBlocks] → ending 3×3 (w → 3) + frame r.
//
// NAFBlock(c): y = x + β ⊙ conv3(SCA(SG(dw3×3(conv1(LN(x)))))),
//              out = y + γ ⊙ conv5(SG(conv4(LN(y)))),
// SG the simple gate (channel halves multiplied), SCA the simplified channel
// attention t · conv(avgpool(t)), LN the per-pixel channel layer norm. β and
// γ start at 0, so a fresh network is the identity on frame r plus the
// intro → ending path. Parameter names follow NAFNet's ("encoders.0.0.conv1.weight");
// tools/restorer_torch.py is the same network in PyTorch.
#pragma once

#include <vkjr2/nets/autograd.hpp>
#include <vkjr2/nets/face_box.hpp>
#include <vkjr2/nets/layers.hpp>

#include <cstdint>
#include <filesystem>
#include <map>
#include <memory>
#include <span>
#include <string>
#include <vector>

namespace vkjr2::jr2 {

struct RestorerConfig {
  int frames = 8;                        // T
  int width = 16;                        // w: channels at full resolution
  std::vector<int> enc_blocks{1, 1, 1};  // NAFBlocks per encoder level (L = size)
  int middle_blocks = 1;
  std::vector<int> dec_blocks{1, 1, 1};  // per decoder level, deepest first

  int levels() const noexcept { return int(enc_blocks.size()); }
  int reference_frame() const noexcept { return frames / 2; }
  // Throws InvalidArgument naming the field and the fix.
  void validate() const;
  // Parameters of the network (Σ numel).
  std::int64_t parameter_count() const;
  // Multiply-adds ×2 of one forward on an H×W input (after padding),
  // convolutions and the gate/attention/norm arithmetic.
  double flops(std::int64_t height, std::int64_t width) const;
  // As file metadata (decimal strings, block lists "1,1,1") and back; from
  // throws InvalidArgument naming `source` and the key.
  std::map<std::string, std::string> metadata() const;
  static RestorerConfig from_metadata(const std::map<std::string, std::string>& meta,
                                      const std::string& source);
};

// "1,1,2" → {1, 1, 2}; throws InvalidArgument naming `what` for anything else.
std::vector<int> parse_block_list(const std::string& text, const std::string& what);

class NafBlock : public nets::Module {
 public:
  NafBlock(const Device& device, int channels, std::uint32_t seed);
  nets::Var forward(nets::Tape& t, const nets::Var& x) const;

  nets::Var norm1_weight, norm1_bias, norm2_weight, norm2_bias, beta, gamma;

 private:
  // residual + conv(h) · scale[c] as one convolution with the residual in its
  // epilogue, its weight and bias scaled per output channel.
  nets::Var scaled_residual(nets::Tape& t, const nets::Conv2d& conv, const nets::ConvPlans& plans,
                            const nets::Var& h, const nets::Var& scale,
                            const nets::Var& residual) const;

  nets::Conv2d *conv1_, *conv2_, *sca_, *conv3_, *conv4_, *conv5_;
  nets::ConvPlans conv3_plans_, conv5_plans_;  // of the scaled weights
};

class Restorer : public nets::Module {
 public:
  // Fresh weights from `seed` (PyTorch's default initialization; β, γ = 0).
  Restorer(const Device& device, const RestorerConfig& config, std::uint32_t seed);

  // A restorer file (save(), or a `vkjr2 restore-train` checkpoint): the
  // configuration from its metadata, then every weight. Errors name the file.
  static std::unique_ptr<Restorer> load(const Device& device, const std::filesystem::path& path);
  // Weights and configuration, written atomically; `metadata` adds keys
  // (training command, data, ...).
  void save(const std::filesystem::path& path,
            const std::map<std::string, std::string>& metadata = {}) const;

  // frames [N, 3T, H, W] → restored reference frame [N, 3, H, W].
  nets::Var forward(nets::Tape& t, const nets::Var& frames) const;

  const RestorerConfig& config() const noexcept { return config_; }

 private:
  RestorerConfig config_;
  nets::Conv2d* intro_;
  nets::Conv2d* ending_;
  std::vector<std::vector<NafBlock*>> encoders_, decoders_;
  std::vector<NafBlock*> middle_;
  std::vector<nets::Conv2d*> downs_, ups_;
};

// The shipped restorer, artifacts/restorer_default.safetensors (made by
// `vkjr2 restore-train`), in the folder the simulator's shipped models are
// found in ($VKJR2_ARTIFACT_DIR, else installed, else the source tree).
std::filesystem::path default_restorer_path();

// The frames a restorer of T frames reads to restore frame `index` of a clip
// of `count`: the T around it with `index` at the reference position T / 2,
// indices clamped into the clip (the first and last frames repeat near the
// ends and when the clip is shorter than T).
std::vector<std::size_t> restore_window(std::size_t count, std::size_t index, int frames);

// Frames [1, 3, H, W] stacked on the channels: [1, 3·count, H, W] (the
// restorer's input).
Tensor stack_frames(Stream& stream, std::span<const Tensor> frames);

// 0..1 planes as 0..255 pixels, clamped as a saved 8-bit frame is:
// 255·min(max(x, 0), 1) (the recognition pipeline's input scale).
Tensor to_pixels(Stream& stream, const Tensor& unit);

// The classical peer of the restorer (docs/restoration.md): the temporal
// mean of the frames — the tilt jitter averages out, as in a long exposure —
// sharpened by unsharp masking, m + amount·(m − G_σ ⊛ m), the Gaussian of
// radius ⌈3σ⌉ normalized inside the image at the borders. frames: [1, 3, H, W]
// each; returns [1, 3, H, W].
// The defaults were chosen on the benchmark's val split (docs/restoration.md §5).
struct ClassicalOptions {
  double sigma_px = 2.5;
  double amount = 0.5;
};
Tensor classical_restore(Stream& stream, std::span<const Tensor> frames,
                         const ClassicalOptions& options = {});

// ---- restoring the faces of a full frame ------------------------------------

// A region of a frame in pixels (top-left corner, size).
struct Region {
  int x = 0, y = 0, width = 0, height = 0;
  bool operator==(const Region&) const = default;
};

// The regions of a frame to restore for these face boxes (image pixels,
// strongest first): each box grown by `margin` × its larger side on every
// side (context for the restorer), made square, rounded up to a multiple of
// `multiple` (the restorer's 2^levels) and moved inside the image, shrunk
// to it only when larger. A box whose region overlaps an earlier region
// (IoU ≥ 0.3: the same face seen in another frame) adds none.
std::vector<Region> face_regions(std::span<const nets::FaceBox> boxes, int height, int width,
                                 double margin = 0.5, int multiple = 8);

// Blends patch [3, r.height, r.width] into frame [3, height, width] (planes)
// at r: weight 1 inside, falling to 0 along a raised-cosine ramp `feather`
// pixels wide at the region's edges, except where an edge is the image's.
void paste_region(std::span<float> frame, int height, int width, std::span<const float> patch,
                  const Region& r, int feather);

}  // namespace vkjr2::jr2
