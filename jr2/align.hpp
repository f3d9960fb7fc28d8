// Differentiable face alignment: 68 landmarks → 5 points → similarity
// transform (closed-form least squares) → affine grid → bilinear grid-sample
// to a canonical crop. Gradients flow from the crop to the frame's pixels
// (not through the landmarks, as in CVLface's aligner).
#pragma once

#include <vkjr2/nets/face_box.hpp>
#include <vkjr2/nets/ops.hpp>

#include <array>
#include <span>

namespace vkjr2::jr2 {

struct Point2 {
  double x = 0, y = 0;
};

// ArcFace's canonical 5 points in a 112×112 crop: eye centres, nose tip,
// mouth corners (insightface).
inline constexpr std::array<Point2, 5> kArcFace112{{{38.2946, 51.6963},
                                                    {73.5318, 51.5014},
                                                    {56.0252, 71.7366},
                                                    {41.5493, 92.3655},
                                                    {70.7299, 92.2041}}};

// The same template scaled to a size×size crop (e.g. 150 for the dlib net).
std::array<Point2, 5> canonical_points(int size);

// Five points from 68 iBUG landmarks given as x0, y0, x1, y1, … (136 values):
// mean of 36–41 (subject's right eye), mean of 42–47, 30 (nose tip), 48 and
// 54 (mouth corners). Throws InvalidArgument unless 136 finite values.
std::array<Point2, 5> five_points(std::span<const float> landmarks68_xy);

// [x'; y'] = [[a, −b], [b, a]] [x; y] + [tx; ty]: rotation, uniform scale
// and translation.
struct Similarity {
  double a = 1, b = 0, tx = 0, ty = 0;
  Point2 apply(Point2 p) const { return {a * p.x - b * p.y + tx, b * p.x + a * p.y + ty}; }
  Similarity inverse() const;
};

// Least-squares similarity taking src onto dst (Umeyama without reflection):
// with centred points p̃, q̃: a = Σ p̃·q̃ / Σ|p̃|², b = Σ (p̃x q̃y − p̃y q̃x) / Σ|p̃|².
// Throws InvalidArgument for fewer than 2 points, sizes that differ, or
// coincident source points.
Similarity fit_similarity(std::span<const Point2> src, std::span<const Point2> dst);

// theta [2×3] for affine_grid/grid_sample (align_corners = false) so that
// output pixel (u, v) of an out_w×out_h crop samples the input image at
// image_to_crop⁻¹(u, v) (pixel centres at integer coordinates).
std::array<float, 6> crop_theta(const Similarity& image_to_crop, std::int64_t in_w,
                                std::int64_t in_h, std::int64_t out_w, std::int64_t out_h);

// The aligned crop [1, C, size, size] of image [1, C, H, W]: zeros outside
// the frame. Differentiable with respect to the image.
nets::Var align_crop(nets::Tape& t, const nets::Var& image, const Similarity& image_to_crop,
                     int size);

// Convenience: five points → similarity onto canonical_points(size) → crop.
nets::Var align_face(nets::Tape& t, const nets::Var& image, std::span<const float> landmarks68_xy,
                     int size);

// ---- face-api's recognition crop ------------------------------------------
// The box face-api cuts the recognition chip from (no warp: an axis-aligned
// crop, then pad to square and resize to 150²; nets/face_recognition.hpp).

// face-api's dlib alignment rect (FaceLandmarks.alignDlib, what
// computeFaceDescriptors uses): eye centres = mean of points 36–41 and 42–47,
// mouth centre = mean of 48–67; size = floor(mean eye-to-mouth distance /
// 0.45); ref = mean of the three centres; x = floor(max(0, ref.x − 0.5·size)),
// y = floor(max(0, ref.y − 0.43·size)); width = min(size, image_w + x),
// height = min(size, image_h + y). Not yet clipped to the image.
// landmarks68_xy: 136 values x0, y0, x1, y1, … in image pixels.
nets::FaceBox face_api_dlib_rect(std::span<const double> landmarks68_xy, int image_w, int image_h);
// The recognition crop face-api takes: nets::clip_at_image_borders(face_api_dlib_rect(…)).
// Throws InvalidArgument for a landmark count other than 68 points, non-finite
// values or a non-positive image size. The double overload reproduces
// face-api's float64 arithmetic bit for bit; the float one converts first.
nets::FaceBox face_api_chip_box(std::span<const double> landmarks68_xy, int image_w, int image_h);
nets::FaceBox face_api_chip_box(std::span<const float> landmarks68_xy, int image_w, int image_h);

}  // namespace vkjr2::jr2
