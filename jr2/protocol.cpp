#include <vkjr2/jr2/protocol.hpp>
#include <vkjr2/kernels/metrics.hpp>
#include <vkjr2/runtime/error.hpp>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <string>

namespace vkjr2::jr2 {
namespace {

bool near_centre(const nets::FaceBox& b, double w, double h, double radius) {
  const double dx = b.x + b.width / 2 - w / 2, dy = b.y + b.height / 2 - h / 2;
  const double r = radius * std::min(w, h);
  return dx * dx + dy * dy <= r * r;
}

}  // namespace

const char* align_mode_name(AlignMode mode) noexcept {
  return mode == AlignMode::similarity ? "similarity" : "face_api";
}

void check_protocol_options(const ProtocolOptions& o) {
  const auto fail = [](const std::string& what, const std::string& problem,
                       const std::string& fix) { throw InvalidArgument(what, problem, fix); };
  if (o.input_sizes.empty()) fail("input sizes", "none given", "name at least one, e.g. 416");
  for (int s : o.input_sizes) {
    if (s < 32 || s % 32 != 0 || s > 2048) {
      fail("input sizes", std::to_string(s) + " is not a multiple of 32 in 32..2048",
           "use sizes such as 160, 320, 416, 608");
    }
  }
  if (!(o.score_threshold > 0 && o.score_threshold < 1) ||
      !(o.track_threshold > 0 && o.track_threshold <= o.score_threshold)) {
    fail("thresholds",
         "score threshold " + std::to_string(o.score_threshold) + ", track threshold " +
             std::to_string(o.track_threshold),
         "use 0 < track threshold ≤ score threshold < 1");
  }
  if (!(o.track_iou > 0 && o.track_iou <= 1) || !(o.anchor_radius > 0 && o.anchor_radius <= 1) ||
      !(o.gallery_face_share > 0 && o.gallery_face_share <= 1)) {
    fail("track", "track IoU, anchor radius and gallery face share must be in (0, 1]",
         "keep the defaults (0.3, 0.25, 0.5) unless the clips are cut otherwise");
  }
  if (o.aligns.empty()) fail("align", "no alignment", "name face_api and/or similarity");
  if (o.aligned_crop && (o.aligns.size() != 1 || o.aligns[0] != AlignMode::similarity)) {
    fail("align", "align-first restoration with an alignment other than similarity only",
         "evaluate align-first models with --align similarity");
  }
}

ProbePipeline::ProbePipeline(const FaceAnalyzer& analyzer, ProtocolOptions options)
    : analyzer_(analyzer), options_(std::move(options)) {
  check_protocol_options(options_);
}

std::vector<ProbePipeline::Detection> ProbePipeline::detect_all(Stream& stream, const Tensor& image,
                                                                float threshold) const {
  std::vector<Detection> out;
  FaceOptions fo;
  fo.score_threshold = threshold;
  for (std::size_t s = 0; s < options_.input_sizes.size(); ++s) {
    fo.input_size = options_.input_sizes[s];
    for (const auto& d : analyzer_.detect(stream, image, fo)) out.push_back({d, int(s)});
  }
  return out;
}

ProbeOutcome ProbePipeline::run(Stream& stream, int frame_count,
                                const std::function<Tensor(int)>& frame, std::uint64_t seed) const {
  const ProtocolOptions& o = options_;
  ProbeOutcome out;
  const std::vector<int> picked = sample_frames(frame_count, o.sampler, seed);
  std::vector<Tensor> images;
  std::vector<std::vector<Detection>> dets;
  // Pass 1: every detection down to the track's bar, and the anchor.
  const Detection* anchor = nullptr;
  double w = 0, h = 0;
  using Clock = std::chrono::steady_clock;
  const auto since = [](Clock::time_point t0) {
    return std::chrono::duration<double>(Clock::now() - t0).count();
  };
  for (int f : picked) {
    auto t0 = Clock::now();
    images.push_back(frame(f));
    out.seconds.frames += since(t0);
    t0 = Clock::now();
    const Shape& s = images.back().shape();
    if (s.rank() != 4 || s[0] != 1 || s[1] != 3) {
      throw InvalidArgument("ProbePipeline::run",
                            "frame " + std::to_string(f) + " has shape " + s.str(),
                            "pass [1, 3, H, W] RGB frames");
    }
    w = double(s[3]);
    h = double(s[2]);
    dets.push_back(detect_all(stream, images.back(), o.track_threshold));
    out.seconds.detect += since(t0);
  }
  for (const auto& frame_dets : dets) {
    for (const Detection& d : frame_dets) {
      if (d.det.score >= o.score_threshold && near_centre(d.det.box, w, h, o.anchor_radius) &&
          (anchor == nullptr || d.det.score > anchor->det.score)) {
        anchor = &d;
      }
    }
  }
  // Pass 2: per frame, the three rules; the track's detections are located
  // (landmarks), then embedded as one batch per alignment.
  out.descriptors.resize(o.aligns.size());
  out.templates.resize(o.aligns.size());
  std::vector<Face> tracked_faces;
  std::vector<Tensor> tracked_images;
  std::vector<int> tracked_frames;
  for (std::size_t i = 0; i < picked.size(); ++i) {
    FrameOutcome fo;
    fo.frame = picked[i];
    const Detection* best = nullptr;
    for (const Detection& d : dets[i]) {
      const bool strong_centre =
          d.det.score >= o.score_threshold && near_centre(d.det.box, w, h, o.anchor_radius);
      if (strong_centre) {
        fo.multi_scale = true;
        if (d.scale == 0) fo.single_scale = true;
      }
      const bool on_track =
          strong_centre ||
          (anchor != nullptr && nets::box_iou(d.det.box, anchor->det.box) >= o.track_iou);
      if (on_track && (best == nullptr || d.det.score > best->det.score)) best = &d;
    }
    if (best != nullptr) {
      fo.tracked = true;
      fo.box = best->det.box;
      fo.score = best->det.score;
      const auto t0 = Clock::now();
      tracked_faces.emplace_back();
      analyzer_.locate(stream, images[i], best->det, tracked_faces.back());
      tracked_images.push_back(images[i]);
      tracked_frames.push_back(picked[i]);
      out.seconds.landmarks += since(t0);
    }
    out.frames.push_back(fo);
  }
  const auto t_embed = Clock::now();
  for (std::size_t a = 0; a < o.aligns.size() && !tracked_faces.empty(); ++a) {
    if (o.aligned_crop) {  // align-first: the caller's crops, described as one batch
      const std::int64_t size = nets::kRecognitionInputSize, per_face = 3 * size * size;
      const auto n = std::int64_t(tracked_faces.size());
      const Tensor batch = Tensor::empty(stream.device(), Shape{n, 3, size, size});
      for (std::int64_t k = 0; k < n; ++k) {
        const Face& f = tracked_faces[std::size_t(k)];
        const std::vector<float> lm(f.landmarks.begin(), f.landmarks.end());
        const Similarity s = fit_similarity(five_points(lm), canonical_points(int(size)));
        stream.copy(o.aligned_crop(stream, tracked_frames[std::size_t(k)], s),
                    batch.view(Shape{1, 3, size, size}, k * per_face));
      }
      const Tensor d = analyzer_.recognition_net().describe(stream, batch);
      stream.run();
      const std::vector<float> all = d.download();
      const std::size_t dim = all.size() / std::size_t(n);
      for (std::size_t k = 0; k < std::size_t(n); ++k) {
        out.descriptors[a].emplace_back(all.begin() + std::ptrdiff_t(k * dim),
                                        all.begin() + std::ptrdiff_t((k + 1) * dim));
      }
      continue;
    }
    const std::vector<bool> ok =
        analyzer_.embed_batch(stream, tracked_images, o.aligns[a], tracked_faces);
    for (std::size_t k = 0; k < ok.size(); ++k) {
      if (ok[k]) out.descriptors[a].push_back(tracked_faces[k].descriptor);
    }
  }
  out.seconds.align_embed = since(t_embed);
  const auto t0 = Clock::now();
  for (std::size_t a = 0; a < o.aligns.size(); ++a) {
    if (!out.descriptors[a].empty()) out.templates[a] = make_template(out.descriptors[a], o.fusion);
  }
  out.seconds.fusion = since(t0);
  return out;
}

std::vector<std::vector<float>> ProbePipeline::describe_gallery(Stream& stream,
                                                                const Tensor& image) const {
  const ProtocolOptions& o = options_;
  const Shape& s = image.shape();
  const double w = double(s[3]), h = double(s[2]);
  nets::FaceDetection chosen;
  bool found = false;
  for (const Detection& d : detect_all(stream, image, o.score_threshold)) {
    if (near_centre(d.det.box, w, h, o.anchor_radius) && (!found || d.det.score > chosen.score)) {
      chosen = d.det;
      found = true;
    }
  }
  if (!found) {
    const double side = o.gallery_face_share * std::min(w, h);
    chosen.box = {(w - side) / 2, (h - side) / 2, side, side};
    chosen.score = 0;
  }
  std::vector<std::vector<float>> out;
  Face face;
  analyzer_.locate(stream, image, chosen, face);
  for (AlignMode a : o.aligns) {
    if (!analyzer_.embed(stream, image, a, face)) {
      throw Error("describe_gallery",
                  "the gallery face's crop falls outside its " + std::to_string(int(w)) + "×" +
                      std::to_string(int(h)) + " image",
                  "enrol clips with the face inside them (vkjr2 dataset make cuts them so)");
    }
    out.push_back(make_template(std::vector<std::vector<float>>{face.descriptor}, o.fusion));
  }
  return out;
}

ClipQuality clip_quality(Stream& stream, std::span<const Tensor> frames, const Tensor& clean) {
  const Shape& cs = clean.shape();
  if (frames.empty() || cs.rank() != 4 || cs[0] != 1) {
    throw InvalidArgument(
        "clip_quality",
        std::to_string(frames.size()) + " frames against a clean clip of shape " + cs.str(),
        "pass [1, 3, H, W] frames and their [1, 3, H, W] clean clip");
  }
  const auto n = std::int64_t(frames.size());
  const std::int64_t per = cs[1] * cs[2] * cs[3];
  const Shape batch{n, cs[1], cs[2], cs[3]};
  const Tensor x = Tensor::empty(stream.device(), batch), y = Tensor::empty(stream.device(), batch);
  for (std::int64_t i = 0; i < n; ++i) {
    const Tensor& f = frames[std::size_t(i)];
    if (!(f.shape() == cs)) {
      throw InvalidArgument("clip_quality",
                            "frame " + std::to_string(i) + " has shape " + f.shape().str() +
                                ", the clean clip " + cs.str(),
                            "compare frames of the clip's size");
    }
    stream.copy(f, x.view(cs, i * per));
    stream.copy(clean, y.view(cs, i * per));
  }
  const Tensor psnr = Tensor::empty(stream.device(), Shape{n});
  const Tensor ssim = Tensor::empty(stream.device(), Shape{n});
  kernels::psnr(stream, x, y, 255.f, psnr);
  kernels::ssim(stream, x, y, 255.f, ssim);
  stream.run();
  ClipQuality q;
  for (float v : psnr.download()) q.psnr_db += double(v) / double(n);
  for (float v : ssim.download()) q.ssim += double(v) / double(n);
  return q;
}

}  // namespace vkjr2::jr2
