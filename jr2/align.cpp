#include <vkjr2/jr2/align.hpp>
#include <vkjr2/runtime/error.hpp>

#include <algorithm>
#include <array>
#include <cmath>
#include <string>
#include <vector>

namespace vkjr2::jr2 {

std::array<Point2, 5> canonical_points(int size) {
  if (size <= 0) {
    throw InvalidArgument("canonical_points", "crop size " + std::to_string(size) + " must be > 0",
                          "use e.g. 112 (ArcFace) or 150 (dlib)");
  }
  std::array<Point2, 5> out{};
  const double s = double(size) / 112.0;
  for (std::size_t i = 0; i < 5; ++i) out[i] = {kArcFace112[i].x * s, kArcFace112[i].y * s};
  return out;
}

std::array<Point2, 5> five_points(std::span<const float> lm) {
  if (lm.size() != 136) {
    throw InvalidArgument("five_points",
                          "expected 68 landmarks (136 values), got " + std::to_string(lm.size()),
                          "pass x0, y0, …, x67, y67");
  }
  for (float v : lm) {
    if (!std::isfinite(v)) {
      throw InvalidArgument("five_points", "a landmark coordinate is NaN or infinite",
                            "check the landmark detector's input");
    }
  }
  const auto pt = [&](int i) { return Point2{lm[2 * std::size_t(i)], lm[2 * std::size_t(i) + 1]}; };
  const auto mean = [&](int from, int to) {
    Point2 m;
    for (int i = from; i <= to; ++i) {
      m.x += lm[2 * std::size_t(i)];
      m.y += lm[2 * std::size_t(i) + 1];
    }
    const double n = to - from + 1;
    return Point2{m.x / n, m.y / n};
  };
  return {mean(36, 41), mean(42, 47), pt(30), pt(48), pt(54)};
}

Similarity Similarity::inverse() const {
  const double d = a * a + b * b;
  Similarity inv{a / d, -b / d, 0, 0};
  const Point2 t = inv.apply({tx, ty});
  inv.tx = -t.x;
  inv.ty = -t.y;
  return inv;
}

Similarity fit_similarity(std::span<const Point2> src, std::span<const Point2> dst) {
  if (src.size() != dst.size() || src.size() < 2) {
    throw InvalidArgument("fit_similarity",
                          "needs ≥ 2 point pairs, got " + std::to_string(src.size()) + " and " +
                              std::to_string(dst.size()),
                          "pass matching point lists");
  }
  Point2 ps, qs;
  for (std::size_t i = 0; i < src.size(); ++i) {
    ps.x += src[i].x;
    ps.y += src[i].y;
    qs.x += dst[i].x;
    qs.y += dst[i].y;
  }
  const double n = double(src.size());
  ps = {ps.x / n, ps.y / n};
  qs = {qs.x / n, qs.y / n};
  double norm = 0, dot = 0, cross = 0;
  for (std::size_t i = 0; i < src.size(); ++i) {
    const double px = src[i].x - ps.x, py = src[i].y - ps.y;
    const double qx = dst[i].x - qs.x, qy = dst[i].y - qs.y;
    norm += px * px + py * py;
    dot += px * qx + py * qy;
    cross += px * qy - py * qx;
  }
  if (!(norm > 1e-12) || !std::isfinite(norm)) {
    throw InvalidArgument("fit_similarity", "the source points coincide (or are not finite)",
                          "pass distinct landmark positions");
  }
  Similarity s{dot / norm, cross / norm, 0, 0};
  const Point2 m = s.apply(ps);
  s.tx = qs.x - m.x;
  s.ty = qs.y - m.y;
  return s;
}

std::array<float, 6> crop_theta(const Similarity& image_to_crop, std::int64_t in_w,
                                std::int64_t in_h, std::int64_t out_w, std::int64_t out_h) {
  // Normalized output coordinate xn ↦ crop pixel u = (W_out·xn + W_out − 1)/2
  // ↦ image pixel x = M⁻¹(u, v) ↦ normalized gx = (2x + 1)/W_in − 1.
  const Similarity inv = image_to_crop.inverse();
  const double su = double(out_w) / 2, cu = double(out_w - 1) / 2;
  const double sv = double(out_h) / 2, cv = double(out_h - 1) / 2;
  const double gx = 2.0 / double(in_w), gy = 2.0 / double(in_h);
  const double ox = 1.0 / double(in_w) - 1, oy = 1.0 / double(in_h) - 1;
  // x = a u − b v + tx, y = b u + a v + ty with u = su·xn + cu, v = sv·yn + cv.
  const double xa = inv.a * su, xb = -inv.b * sv, xc = inv.a * cu - inv.b * cv + inv.tx;
  const double ya = inv.b * su, yb = inv.a * sv, yc = inv.b * cu + inv.a * cv + inv.ty;
  return {float(gx * xa), float(gx * xb), float(gx * xc + ox),
          float(gy * ya), float(gy * yb), float(gy * yc + oy)};
}

nets::Var align_crop(nets::Tape& t, const nets::Var& image, const Similarity& image_to_crop,
                     int size) {
  const Shape& s = image.shape();
  if (s.rank() != 4 || s[0] != 1) {
    throw InvalidArgument("align_crop", "image has shape " + s.str(),
                          "pass one NCHW image [1, C, H, W]");
  }
  if (size <= 0 || size > 4096) {
    throw InvalidArgument("align_crop", "crop size " + std::to_string(size) + " out of range",
                          "use 1..4096 (112 for ArcFace, 150 for dlib)");
  }
  const auto theta = crop_theta(image_to_crop, s[3], s[2], size, size);
  const nets::Var th(Tensor::from(image.value().device(), Shape{1, 2, 3}, theta));
  const nets::Var grid = nets::affine_grid(t, th, size, size, false);
  return nets::grid_sample(t, image, grid, {kernels::SamplePadding::zeros, false});
}

nets::Var align_face(nets::Tape& t, const nets::Var& image, std::span<const float> landmarks68_xy,
                     int size) {
  const auto src = five_points(landmarks68_xy);
  const auto dst = canonical_points(size);
  return align_crop(t, image, fit_similarity(src, dst), size);
}

// ---- face-api's recognition crop ------------------------------------------

nets::FaceBox face_api_dlib_rect(std::span<const double> lm, int image_w, int image_h) {
  if (lm.size() != 136) {
    throw InvalidArgument("face_api_chip_box",
                          "landmarks68_xy holds " + std::to_string(lm.size()) +
                              " values, expected 136 (68 points × x, y)",
                          "pass FaceLandmark68Net's 68 points in image pixels");
  }
  for (std::size_t i = 0; i < lm.size(); ++i) {
    if (!std::isfinite(lm[i])) {
      throw InvalidArgument("face_api_chip_box",
                            "landmark " + std::to_string(i / 2) + " has a non-finite " +
                                (i % 2 == 0 ? "x" : "y") + " coordinate",
                            "check the landmark net's input and output for NaN/Inf");
    }
  }
  if (image_w <= 0 || image_h <= 0) {
    throw InvalidArgument("face_api_chip_box",
                          "image size " + std::to_string(image_w) + "×" + std::to_string(image_h) +
                              " is not positive",
                          "pass the width and height of the frame the landmarks belong to");
  }
  // getCenterPoint: Σ from (0, 0) in order, then divided by the count.
  const auto centre = [&](std::size_t first, std::size_t last) {
    double sx = 0, sy = 0;
    for (std::size_t i = first; i <= last; ++i) {
      sx += lm[2 * i];
      sy += lm[2 * i + 1];
    }
    const auto n = double(last - first + 1);
    return std::array<double, 2>{sx / n, sy / n};
  };
  const std::array<std::array<double, 2>, 3> centres = {centre(36, 41), centre(42, 47),
                                                        centre(48, 67)};
  const auto& mouth = centres[2];
  const auto dist_to_mouth = [&](const std::array<double, 2>& p) {
    const double dx = mouth[0] - p[0], dy = mouth[1] - p[1];
    return std::sqrt(dx * dx + dy * dy);
  };
  const double eye_to_mouth = (dist_to_mouth(centres[0]) + dist_to_mouth(centres[1])) / 2;
  constexpr double kRelX = 0.5, kRelY = 0.43, kRelScale = 0.45;  // FaceLandmarks.ts
  const double size = std::floor(eye_to_mouth / kRelScale);
  double rx = 0, ry = 0;
  for (const auto& c : centres) {
    rx += c[0];
    ry += c[1];
  }
  rx /= 3;
  ry /= 3;
  const double x = std::floor(std::max(0.0, rx - kRelX * size));
  const double y = std::floor(std::max(0.0, ry - kRelY * size));
  return nets::FaceBox{x, y, std::min(size, double(image_w) + x),
                       std::min(size, double(image_h) + y)};
}

nets::FaceBox face_api_chip_box(std::span<const double> lm, int image_w, int image_h) {
  return nets::clip_at_image_borders(face_api_dlib_rect(lm, image_w, image_h), image_w, image_h);
}

nets::FaceBox face_api_chip_box(std::span<const float> lm, int image_w, int image_h) {
  const std::vector<double> d(lm.begin(), lm.end());
  return face_api_chip_box(std::span<const double>(d), image_w, image_h);
}

}  // namespace vkjr2::jr2
