// The JR² recognition pipeline for one probe video (docs/eval.md):
//
//   temporal sampler → detect (several input sizes, pooled) → the
//   probe's face track → 68 landmarks → alignment (face-api's box crop
//   and/or the 5-point similarity alignment) → descriptor → template.
//
// The probe's face is the one at the clip's centre (a benchmark clip is cut
// around it). Its anchor is the strongest detection (score ≥ the threshold,
// any input size) centred within anchor_radius of the clip's centre in any
// sampled frame; in each frame the track keeps the strongest detection that
// is such a detection itself or overlaps the anchor (IoU ≥ track_iou) with a
// score ≥ track_threshold: a face found in the neighbouring frames is
// searched for where it was, with a lower bar. A probe where no frame
// yields a face has no template (a failure to acquire).
#pragma once

#include <vkjr2/jr2/faces.hpp>
#include <vkjr2/jr2/metrics.hpp>
#include <vkjr2/jr2/sampler.hpp>

#include <cstdint>
#include <functional>
#include <span>
#include <vector>

namespace vkjr2::jr2 {

struct ProtocolOptions {
  FrameSampler sampler;  // segments:4x2
  // Detector input sizes; the first alone is the single-scale baseline.
  std::vector<int> input_sizes = {416, 160, 320};
  float score_threshold = 0.5f;
  float track_threshold = 0.2f;
  double track_iou = 0.3;
  double anchor_radius = 0.25;  // as a share of the clip's shorter side
  // Gallery clips whose face is not detected are described from a centred
  // box of this share of the shorter side (the benchmark's face/clip ratio).
  double gallery_face_share = 0.5;
  std::vector<AlignMode> aligns = {AlignMode::face_api, AlignMode::similarity};
  TemplateFusion fusion = TemplateFusion::norm_weighted;
  // Align-first restoration (docs/jr2.md): when set, the similarity
  // alignment's crop of sampled frame `frame` is aligned_crop(stream, frame,
  // image_to_crop) — [1, 3, 150, 150], 0..255, e.g. the window's frames
  // aligned by that similarity and restored — instead of the frame's own
  // crop. Needs aligns = {similarity} only.
  std::function<Tensor(Stream&, int frame, const Similarity& image_to_crop)> aligned_crop;
};
// Throws InvalidArgument naming the option at fault.
void check_protocol_options(const ProtocolOptions& options);
const char* align_mode_name(AlignMode mode) noexcept;  // "face_api", "similarity"

// Whether the probe's face was found in one sampled frame, three ways.
struct FrameOutcome {
  int frame = 0;
  bool single_scale = false;  // at input_sizes[0], score ≥ threshold, near the centre
  bool multi_scale = false;   // at any input size, score ≥ threshold, near the centre
  bool tracked = false;       // the track's rule (used for the descriptors)
  nets::FaceBox box;          // the tracked detection
  float score = 0;
};

// Host wall time of each stage of one probe (the stages wait for the
// device, so these are the stages' whole cost).
struct StageSeconds {
  double frames = 0;       // fetching the sampled frames (decode, upload: the caller's frame())
  double detect = 0;       // the detector at every input size, the track
  double landmarks = 0;    // 68 landmarks of the tracked faces
  double align_embed = 0;  // crop or alignment, and the descriptor
  double fusion = 0;       // the templates
  double total() const { return frames + detect + landmarks + align_embed + fusion; }
};

struct ProbeOutcome {
  std::vector<FrameOutcome> frames;  // the sampled frames
  StageSeconds seconds;
  // Per alignment (ProtocolOptions::aligns order): the descriptors of the
  // tracked frames, and the template (empty: no face acquired).
  std::vector<std::vector<std::vector<float>>> descriptors;
  std::vector<std::vector<float>> templates;
};

class ProbePipeline {
 public:
  ProbePipeline(const FaceAnalyzer& analyzer, ProtocolOptions options);

  const ProtocolOptions& options() const { return options_; }

  // One probe video of frame_count frames; frame(i) gives frame i as
  // [1, 3, H, W] RGB 0..255 on the device (only the sampled ones are asked
  // for). seed: the sampler's.
  ProbeOutcome run(Stream& stream, int frame_count, const std::function<Tensor(int)>& frame,
                   std::uint64_t seed) const;

  // A gallery clip [1, 3, H, W]: per alignment, its descriptor (the face at
  // the centre, or the centred fallback box).
  std::vector<std::vector<float>> describe_gallery(Stream& stream, const Tensor& image) const;

 private:
  struct Detection {
    nets::FaceDetection det;
    int scale = 0;  // index into input_sizes
  };
  std::vector<Detection> detect_all(Stream& stream, const Tensor& image, float threshold) const;

  const FaceAnalyzer& analyzer_;
  ProtocolOptions options_;
};

// Image quality of a probe's frames against its clean clip: the mean over
// the frames of PSNR (dB) and SSIM (Wang et al. 2004), 8-bit data range.
// frames and clean: [1, 3, H, W], 0..255, all one size (else InvalidArgument).
struct ClipQuality {
  double psnr_db = 0, ssim = 0;
};
ClipQuality clip_quality(Stream& stream, std::span<const Tensor> frames, const Tensor& clean);

// The score of a probe without a template against every gallery identity:
// below every cosine similarity, so it is a miss and never a false alarm.
inline constexpr double kNoTemplateScore = -2.0;

}  // namespace vkjr2::jr2
