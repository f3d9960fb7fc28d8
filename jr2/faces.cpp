#include <vkjr2/jr2/faces.hpp>
#include <vkjr2/runtime/error.hpp>

#include <algorithm>
#include <cmath>
#include <map>

namespace vkjr2::jr2 {

FaceAnalyzer::FaceAnalyzer(const Device& device)
    : detector_(nets::TinyFaceDetector::load(device)),
      landmarks_(nets::FaceLandmark68Net::load(device)),
      recognition_(nets::FaceRecognitionNet::load(device)) {
  detector_->eval();
  landmarks_->eval();
  recognition_->eval();
}

FaceAnalyzer::~FaceAnalyzer() = default;

std::vector<float> FaceAnalyzer::describe_chip(Stream& stream, const Tensor& chip) const {
  nets::Tape t(stream, false);
  const nets::Var input = nets::to_recognition_input(t, nets::Var(chip));
  const nets::Var d = recognition_->forward(t, input);
  stream.run();
  return d.value().download();
}

std::vector<nets::FaceDetection> FaceAnalyzer::detect(Stream& stream, const Tensor& image,
                                                      const FaceOptions& options) const {
  const Shape& s = image.shape();
  if (s.rank() != 4 || s[0] != 1 || s[1] != 3) {
    throw InvalidArgument("FaceAnalyzer::detect", "image has shape " + s.str(),
                          "pass one RGB image [1, 3, H, W] in 0..255");
  }
  std::vector<nets::FaceDetection> all =
      detector_->detect(stream, image, options.input_size, options.score_threshold);
  if (options.extra_input_sizes.empty()) return all;
  for (int size : options.extra_input_sizes) {
    const auto more = detector_->detect(stream, image, size, options.score_threshold);
    all.insert(all.end(), more.begin(), more.end());
  }
  std::vector<nets::FaceBox> boxes;
  std::vector<double> scores;
  for (const auto& d : all) {
    boxes.push_back(d.box);
    scores.push_back(d.score);
  }
  std::vector<nets::FaceDetection> merged;
  for (std::size_t i : nets::non_max_suppression(boxes, scores, nets::kTinyFaceIouThreshold)) {
    merged.push_back(all[i]);
  }
  return merged;
}

bool FaceAnalyzer::describe(Stream& stream, const Tensor& image, const nets::FaceDetection& det,
                            const FaceOptions& options, Face& f) const {
  const int w = int(image.shape()[3]), h = int(image.shape()[2]);
  f.score = det.score;
  f.box = det.box;
  f.cut_by_border = det.box.x < 0 || det.box.y < 0 || det.box.x + det.box.width > w ||
                    det.box.y + det.box.height > h;
  f.landmarks = landmarks_->landmarks_in_image(stream, image, det.box);
  f.chip_box = face_api_chip_box(std::span<const double>(f.landmarks), w, h);
  f.descriptor.clear();
  if (!options.descriptors) return true;
  nets::Tape t(stream, false);
  nets::Var input;
  if (options.align == AlignMode::face_api) {
    if (f.chip_box.width <= 0 || f.chip_box.height <= 0) return false;
    input = nets::to_recognition_input(t, nets::extract_face(t, nets::Var(image), f.chip_box));
  } else {
    const std::vector<float> lm(f.landmarks.begin(), f.landmarks.end());
    input = align_face(t, nets::Var(image), lm, int(nets::kRecognitionInputSize));
  }
  const nets::Var d = recognition_->forward(t, input);
  stream.run();
  f.descriptor = d.value().download();
  return true;
}

std::vector<Face> FaceAnalyzer::analyze(Stream& stream, const Tensor& image,
                                        const FaceOptions& options) const {
  const int w = int(image.shape().rank() == 4 ? image.shape()[3] : 0);
  const int h = int(image.shape().rank() == 4 ? image.shape()[2] : 0);
  std::vector<Face> faces;
  for (const nets::FaceDetection& det : detect(stream, image, options)) {
    const nets::FaceBox clipped = nets::clip_at_image_borders(det.box, w, h);
    if (clipped.width <= 0 || clipped.height <= 0) continue;  // entirely outside the frame
    Face f;
    if (describe(stream, image, det, options, f)) faces.push_back(std::move(f));
  }
  return faces;
}

double descriptor_distance(std::span<const float> a, std::span<const float> b) {
  if (a.size() != b.size() || a.empty()) {
    throw InvalidArgument(
        "descriptor_distance",
        "descriptors of sizes " + std::to_string(a.size()) + " and " + std::to_string(b.size()),
        "compare two descriptors of the same network");
  }
  double s = 0;
  for (std::size_t i = 0; i < a.size(); ++i) s += (double(a[i]) - b[i]) * (double(a[i]) - b[i]);
  return std::sqrt(s);
}

std::vector<Candidate> rank_identities(std::span<const GalleryEntry> gallery,
                                       std::span<const float> probe) {
  std::map<std::string, Candidate> best;
  for (const GalleryEntry& e : gallery) {
    const double d = descriptor_distance(e.descriptor, probe);
    auto [it, inserted] = best.try_emplace(e.identity, Candidate{e.identity, d, e.source});
    if (!inserted && d < it->second.distance) it->second = {e.identity, d, e.source};
  }
  std::vector<Candidate> out;
  out.reserve(best.size());
  for (auto& [id, c] : best) out.push_back(std::move(c));
  std::stable_sort(out.begin(), out.end(),
                   [](const Candidate& a, const Candidate& b) { return a.distance < b.distance; });
  return out;
}

}  // namespace vkjr2::jr2
