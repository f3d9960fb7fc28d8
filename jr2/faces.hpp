// The face stack as one pipeline: detect (TinyFaceDetector) → 68 landmarks
// (FaceLandmark68Net) → align (face-api's dlib box, or our similarity
// alignment) → 128-d descriptor (FaceRecognitionNet). Plus gallery matching.
#pragma once

#include <vkjr2/jr2/align.hpp>
#include <vkjr2/nets/face_landmarks.hpp>
#include <vkjr2/nets/face_recognition.hpp>
#include <vkjr2/nets/tiny_face_detector.hpp>

#include <memory>
#include <string>
#include <vector>

namespace vkjr2::jr2 {

enum class AlignMode : std::uint8_t {
  face_api,    // face-api's axis-aligned dlib box, pad + resize to 150 (matches face-api)
  similarity,  // 5-point similarity onto the canonical template at 150×150 (rotation-invariant)
};

struct FaceOptions {
  int input_size = 416;          // detector input, a multiple of 32
  float score_threshold = 0.5f;  // detector score in (0, 1)
  bool descriptors = true;       // run the recognition net
  AlignMode align = AlignMode::face_api;
};

struct Face {
  float score = 0;
  nets::FaceBox box;              // detection, image pixels
  std::vector<double> landmarks;  // 136: x0, y0, …, image pixels
  nets::FaceBox chip_box;         // the recognition crop (face_api mode)
  std::vector<float> descriptor;  // 128 values (empty without descriptors)
  bool cut_by_border = false;     // the detection box reaches outside the image
};

class FaceAnalyzer {
 public:
  // Loads the three face-api models (nets::face_api_model_dir()).
  explicit FaceAnalyzer(const Device& device);
  ~FaceAnalyzer();
  FaceAnalyzer(const FaceAnalyzer&) = delete;
  FaceAnalyzer& operator=(const FaceAnalyzer&) = delete;

  // Every face in image [1, 3, H, W] (RGB 0..255), highest score first:
  // detect(), then describe() of each. Faces whose crop falls outside the
  // image are dropped.
  std::vector<Face> analyze(Stream& stream, const Tensor& image, const FaceOptions& options) const;
  // The detections at options.input_size, highest score first (face-api's
  // NMS). Throws InvalidArgument for an input size that is not a positive
  // multiple of 32.
  std::vector<nets::FaceDetection> detect(Stream& stream, const Tensor& image,
                                          const FaceOptions& options) const;
  // Landmarks, crop or alignment and (options.descriptors) the descriptor of
  // the detected face in image [1, 3, H, W]: locate(), then embed(). Returns
  // false, leaving `face` partly filled, when face_api alignment's crop falls
  // outside the image.
  bool describe(Stream& stream, const Tensor& image, const nets::FaceDetection& detection,
                const FaceOptions& options, Face& face) const;
  // The face's score, box, 68 landmarks and face-api's crop box (no descriptor).
  void locate(Stream& stream, const Tensor& image, const nets::FaceDetection& detection,
              Face& face) const;
  // face.descriptor from a located face, aligned by `align` (false: the
  // face_api crop falls outside the image).
  bool embed(Stream& stream, const Tensor& image, AlignMode align, Face& face) const;
  // embed() of faces[i] in images[i] for every i, as one batch through the
  // recognition net (one submit). Returns which faces got a descriptor.
  std::vector<bool> embed_batch(Stream& stream, std::span<const Tensor> images, AlignMode align,
                                std::span<Face> faces) const;
  // The descriptor of an already cropped face [1, 3, h, w] (any size; padded
  // to a square and resized to 150 as face-api does).
  std::vector<float> describe_chip(Stream& stream, const Tensor& chip) const;

  const nets::TinyFaceDetector& detector() const { return *detector_; }
  const nets::FaceLandmark68Net& landmark_net() const { return *landmarks_; }
  const nets::FaceRecognitionNet& recognition_net() const { return *recognition_; }

 private:
  std::unique_ptr<nets::TinyFaceDetector> detector_;
  std::unique_ptr<nets::FaceLandmark68Net> landmarks_;
  std::unique_ptr<nets::FaceRecognitionNet> recognition_;
};

// Euclidean distance (face-api's measure; same person below ~0.6).
double descriptor_distance(std::span<const float> a, std::span<const float> b);
inline constexpr double kFaceApiMatchThreshold = 0.6;

// A gallery of labelled descriptors and 1:N search.
struct GalleryEntry {
  std::string identity;
  std::string source;
  std::vector<float> descriptor;
};
struct Candidate {
  std::string identity;
  double distance = 0;  // the smallest over that identity's entries
  std::string source;   // the entry that gave it
};
// Identities ranked by their best distance to `probe`, nearest first.
std::vector<Candidate> rank_identities(std::span<const GalleryEntry> gallery,
                                       std::span<const float> probe);

}  // namespace vkjr2::jr2
