// Face boxes: the detector's output type and the box geometry the face models
// share (face-api's Box: clip at the image borders, crop, IoU). The rule by
// which face-api places the recognition crop from the landmarks is with the
// alignment, in jr2/align.hpp.
#pragma once

#include <vkjr2/nets/ops.hpp>

namespace vkjr2::nets {

// An axis-aligned box in pixels (face-api's Box/Rect: x, y = top-left corner).
struct FaceBox {
  double x = 0, y = 0, width = 0, height = 0;
  bool operator==(const FaceBox&) const = default;
};

// face-api's Box.clipAtImageBorders: x, y clamped to ≥ 0, right/bottom to the
// image, then every field floored. Width/height may come out ≤ 0 (box outside
// the image: face-api then drops the face).
FaceBox clip_at_image_borders(const FaceBox& box, int image_w, int image_h);
// extractFaceTensors for one box: clips `box` to the image like face-api, then
// slices it out of image [N, C, H, W] (all N images, same box) →
// [N, C, height, width]. Differentiable (the gradient lands in the box).
// Throws InvalidArgument when the clipped box is empty (face outside the image).
Var extract_face(Tape& t, const Var& image_nchw, const FaceBox& box);

// Intersection over union of two boxes (0 when they do not overlap).
double box_iou(const FaceBox& a, const FaceBox& b);

}  // namespace vkjr2::nets
