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
  return detector_->detect(stream, image, options.input_size, options.score_threshold);
}

void FaceAnalyzer::locate(Stream& stream, const Tensor& image, const nets::FaceDetection& det,
                          Face& f) const {
  const int w = int(image.shape()[3]), h = int(image.shape()[2]);
  f.score = det.score;
  f.box = det.box;
  f.cut_by_border = det.box.x < 0 || det.box.y < 0 || det.box.x + det.box.width > w ||
                    det.box.y + det.box.height > h;
  f.landmarks = landmarks_->landmarks_in_image(stream, image, det.box);
  f.chip_box = face_api_chip_box(std::span<const double>(f.landmarks), w, h);
  f.descriptor.clear();
}

namespace {

// The recognition net's [1, 3, 150, 150] input for a located face (undefined:
// face-api's crop falls outside the image).
nets::Var recognition_input(nets::Tape& t, const Tensor& image, AlignMode align, const Face& f) {
  if (align == AlignMode::face_api) {
    if (f.chip_box.width <= 0 || f.chip_box.height <= 0) return {};
    return nets::to_recognition_input(t, nets::extract_face(t, nets::Var(image), f.chip_box));
  }
  const std::vector<float> lm(f.landmarks.begin(), f.landmarks.end());
  return align_face(t, nets::Var(image), lm, int(nets::kRecognitionInputSize));
}

}  // namespace

bool FaceAnalyzer::embed(Stream& stream, const Tensor& image, AlignMode align, Face& f) const {
  return embed_batch(stream, std::span<const Tensor>(&image, 1), align, std::span<Face>(&f, 1))
      .front();
}

std::vector<bool> FaceAnalyzer::embed_batch(Stream& stream, std::span<const Tensor> images,
                                            AlignMode align, std::span<Face> faces) const {
  if (images.size() != faces.size()) {
    throw InvalidArgument(
        "FaceAnalyzer::embed_batch",
        std::to_string(images.size()) + " images for " + std::to_string(faces.size()) + " faces",
        "pass each face's image");
  }
  std::vector<bool> ok(faces.size(), false);
  nets::Tape t(stream, false);
  std::vector<nets::Var> inputs;
  std::vector<std::size_t> which;
  for (std::size_t i = 0; i < faces.size(); ++i) {
    nets::Var in = recognition_input(t, images[i], align, faces[i]);
    if (!in.defined()) continue;
    inputs.push_back(std::move(in));
    which.push_back(i);
  }
  if (inputs.empty()) return ok;
  const std::int64_t s = nets::kRecognitionInputSize, per_face = 3 * s * s;
  const auto n = std::int64_t(inputs.size());
  Tensor batch =
      n == 1 ? inputs.front().value() : Tensor::empty(stream.device(), Shape{n, 3, s, s});
  if (n > 1) {
    for (std::int64_t i = 0; i < n; ++i) {
      stream.copy(inputs[std::size_t(i)].value(), batch.view(Shape{1, 3, s, s}, i * per_face));
    }
  }
  const nets::Var d = recognition_->forward(t, nets::Var(batch));
  stream.run();
  const std::vector<float> all = d.value().download();
  const std::size_t dim = all.size() / std::size_t(n);
  for (std::size_t k = 0; k < which.size(); ++k) {
    Face& f = faces[which[k]];
    f.descriptor.assign(all.begin() + std::ptrdiff_t(k * dim),
                        all.begin() + std::ptrdiff_t((k + 1) * dim));
    ok[which[k]] = true;
  }
  return ok;
}

bool FaceAnalyzer::describe(Stream& stream, const Tensor& image, const nets::FaceDetection& det,
                            const FaceOptions& options, Face& f) const {
  locate(stream, image, det, f);
  return !options.descriptors || embed(stream, image, options.align, f);
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
