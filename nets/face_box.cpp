#include <vkjr2/nets/face_box.hpp>
#include <vkjr2/runtime/error.hpp>

#include <algorithm>
#include <cmath>
#include <string>

namespace vkjr2::nets {

FaceBox clip_at_image_borders(const FaceBox& b, int image_w, int image_h) {
  const double x = std::max(b.x, 0.0), y = std::max(b.y, 0.0);
  const double w = std::min(b.x + b.width - x, double(image_w) - x);
  const double h = std::min(b.y + b.height - y, double(image_h) - y);
  return FaceBox{std::floor(x), std::floor(y), std::floor(w), std::floor(h)};
}

Var extract_face(Tape& t, const Var& image, const FaceBox& box) {
  if (!image.defined() || image.shape().rank() != 4 || image.numel() == 0) {
    throw InvalidArgument("extract_face",
                          "image has shape " +
                              (image.defined() ? image.shape().str() : std::string("(undefined)")) +
                              ", expected a non-empty NCHW image [N, C, H, W]",
                          "pass a 4-D tensor (image_to_device gives [1, C, H, W])");
  }
  const Shape& s = image.shape();
  if (!std::isfinite(box.x) || !std::isfinite(box.y) || !std::isfinite(box.width) ||
      !std::isfinite(box.height)) {
    throw InvalidArgument("extract_face", "the face box has a non-finite field",
                          "pass the box from face_api_chip_box");
  }
  const FaceBox c = clip_at_image_borders(box, int(s[3]), int(s[2]));
  if (c.width <= 0 || c.height <= 0) {
    throw InvalidArgument("extract_face",
                          "face box (x " + std::to_string(box.x) + ", y " + std::to_string(box.y) +
                              ", " + std::to_string(box.width) + "×" + std::to_string(box.height) +
                              ") lies outside the " + std::to_string(s[3]) + "×" +
                              std::to_string(s[2]) + " image",
                          "pass a box that overlaps the image (face-api drops such faces)");
  }
  return slice(t, image, kernels::SliceStart{0, std::int64_t(c.y), std::int64_t(c.x)},
               Shape{s[0], s[1], std::int64_t(c.height), std::int64_t(c.width)});
}

double box_iou(const FaceBox& a, const FaceBox& b) {
  const double w = std::max(0.0, std::min(a.x + a.width, b.x + b.width) - std::max(a.x, b.x));
  const double h = std::max(0.0, std::min(a.y + a.height, b.y + b.height) - std::max(a.y, b.y));
  const double inter = w * h;
  return inter / (a.width * a.height + b.width * b.height - inter);
}

}  // namespace vkjr2::nets
