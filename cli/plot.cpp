#include "plot.hpp"

#include <vkjr2/runtime/error.hpp>

#include <opencv2/imgproc.hpp>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>

#include "cv_image.hpp"
#include "media.hpp"

namespace vkjr2::cli {
namespace {

constexpr int kWidth = 1000, kHeight = 700;
constexpr int kLeft = 90, kRight = 30, kTop = 50, kBottom = 70;
constexpr int kFont = cv::FONT_HERSHEY_SIMPLEX;

// Colour-blind-safe palette (Okabe & Ito 2008), BGR.
constexpr std::array<std::array<int, 3>, 8> kPalette = {{{178, 114, 0},
                                                         {0, 159, 230},
                                                         {115, 158, 0},
                                                         {167, 121, 204},
                                                         {0, 94, 213},
                                                         {233, 180, 86},
                                                         {66, 228, 240},
                                                         {0, 0, 0}}};

cv::Scalar colour(std::size_t i) {
  const auto& c = kPalette[i % kPalette.size()];
  return {double(c[0]), double(c[1]), double(c[2])};
}

std::string tick_text(double v) {
  char b[32];
  std::snprintf(b, sizeof b, "%g", v);
  return b;
}

void text(cv::Mat& img, const std::string& s, cv::Point at, double scale, bool centre = false) {
  int base = 0;
  const cv::Size size = cv::getTextSize(s, kFont, scale, 1, &base);
  if (centre) at.x -= size.width / 2;
  cv::putText(img, s, at, kFont, scale, cv::Scalar(0, 0, 0), 1, cv::LINE_AA);
}

}  // namespace

void write_plot(const std::filesystem::path& path, const PlotSpec& given, bool force) {
  PlotSpec spec = given;
  if (spec.log_x && !(spec.x_min > 0)) {
    double smallest = spec.x_max;
    for (const auto& s : spec.series) {
      for (const auto& [x, y] : s.points) {
        if (x > 0) smallest = std::min(smallest, x);
      }
    }
    spec.x_min = std::pow(10.0, std::floor(std::log10(smallest)));
  }
  cv::Mat img(kHeight, kWidth, CV_8UC3, cv::Scalar(255, 255, 255));
  const int pw = kWidth - kLeft - kRight, ph = kHeight - kTop - kBottom;
  const double lx0 = spec.log_x ? std::log10(spec.x_min) : spec.x_min;
  const double lx1 = spec.log_x ? std::log10(spec.x_max) : spec.x_max;
  const auto px = [&](double x) {
    double v = spec.log_x ? std::log10(std::max(x, spec.x_min)) : x;
    v = std::clamp(v, lx0, lx1);
    return kLeft + int(std::lround((v - lx0) / (lx1 - lx0) * pw));
  };
  const auto py = [&](double y) {
    const double v = std::clamp(y, spec.y_min, spec.y_max);
    return kTop + ph - int(std::lround((v - spec.y_min) / (spec.y_max - spec.y_min) * ph));
  };
  // Grid and ticks.
  const cv::Scalar grid(225, 225, 225);
  std::vector<double> xticks;
  if (spec.log_x) {
    for (int e = int(std::floor(lx0)); e <= int(std::ceil(lx1)); ++e) {
      const double v = std::pow(10.0, e);
      if (v >= spec.x_min * (1 - 1e-9) && v <= spec.x_max * (1 + 1e-9)) xticks.push_back(v);
    }
  } else {
    const double span = spec.x_max - spec.x_min;
    const double step = span <= 1.0 ? 0.1 : std::pow(10.0, std::floor(std::log10(span / 2)));
    for (double v = spec.x_min; v <= spec.x_max + 1e-9; v += step) xticks.push_back(v);
  }
  for (double v : xticks) {
    cv::line(img, {px(v), kTop}, {px(v), kTop + ph}, grid, 1);
    text(img, tick_text(v), {px(v), kTop + ph + 22}, 0.5, true);
  }
  for (int i = 0; i <= 10; ++i) {
    const double v = spec.y_min + (spec.y_max - spec.y_min) * i / 10.0;
    cv::line(img, {kLeft, py(v)}, {kLeft + pw, py(v)}, grid, 1);
    text(img, tick_text(std::round(v * 1000) / 1000), {kLeft - 45, py(v) + 5}, 0.5);
  }
  cv::rectangle(img, {kLeft, kTop}, {kLeft + pw, kTop + ph}, cv::Scalar(0, 0, 0), 1);
  text(img, spec.title, {kWidth / 2, 30}, 0.7, true);
  text(img, spec.x_label + (spec.log_x ? " (log scale)" : ""), {kLeft + pw / 2, kHeight - 20}, 0.6,
       true);
  // The y label, rotated: drawn on its own image, then turned.
  {
    int base = 0;
    const cv::Size size = cv::getTextSize(spec.y_label, kFont, 0.6, 1, &base);
    cv::Mat label(size.height + base + 4, size.width + 4, CV_8UC3, cv::Scalar(255, 255, 255));
    cv::putText(label, spec.y_label, {2, size.height + 2}, kFont, 0.6, cv::Scalar(0, 0, 0), 1,
                cv::LINE_AA);
    cv::Mat turned;
    cv::rotate(label, turned, cv::ROTATE_90_COUNTERCLOCKWISE);
    const int y0 = std::max(0, kTop + ph / 2 - turned.rows / 2);
    if (y0 + turned.rows <= kHeight && 8 + turned.cols <= kLeft) {
      turned.copyTo(img(cv::Rect(8, y0, turned.cols, turned.rows)));
    }
  }
  // Series.
  for (std::size_t s = 0; s < spec.series.size(); ++s) {
    const auto& pts = spec.series[s].points;
    for (std::size_t i = 1; i < pts.size(); ++i) {
      const cv::Point a(px(pts[i - 1].first), py(pts[i - 1].second));
      const cv::Point b(px(pts[i].first), py(pts[i].second));
      if (spec.steps) {
        cv::line(img, a, {b.x, a.y}, colour(s), 2, cv::LINE_AA);
        cv::line(img, {b.x, a.y}, b, colour(s), 2, cv::LINE_AA);
      } else {
        cv::line(img, a, b, colour(s), 2, cv::LINE_AA);
      }
    }
    if (pts.size() == 1) cv::circle(img, {px(pts[0].first), py(pts[0].second)}, 3, colour(s), -1);
  }
  // Legend, bottom right inside the axes.
  if (!spec.series.empty()) {
    int wmax = 0;
    for (const auto& s : spec.series) {
      int base = 0;
      wmax = std::max(wmax, cv::getTextSize(s.label, kFont, 0.45, 1, &base).width);
    }
    const int row = 20, lw = wmax + 50, lh = row * int(spec.series.size()) + 10;
    const cv::Point origin(kLeft + pw - lw - 10, spec.legend_top ? kTop + 10 : kTop + ph - lh - 10);
    cv::rectangle(img, origin, origin + cv::Point(lw, lh), cv::Scalar(255, 255, 255), cv::FILLED);
    cv::rectangle(img, origin, origin + cv::Point(lw, lh), cv::Scalar(120, 120, 120), 1);
    for (std::size_t s = 0; s < spec.series.size(); ++s) {
      const int y = origin.y + 15 + row * int(s);
      cv::line(img, {origin.x + 8, y - 4}, {origin.x + 36, y - 4}, colour(s), 3, cv::LINE_AA);
      cv::putText(img, spec.series[s].label, {origin.x + 44, y}, kFont, 0.45, cv::Scalar(0, 0, 0),
                  1, cv::LINE_AA);
    }
  }
  write_image(path, image_from_bgr(img), force);
}

void write_matrix_plot(const std::filesystem::path& path, const MatrixSpec& spec, bool force) {
  const int nr = int(spec.rows.size()), nc = int(spec.columns.size());
  if (nr == 0 || nc == 0 || spec.panels.empty()) {
    throw InvalidArgument("write_matrix_plot", "no categories or no panels",
                          "give at least one row, one column and one panel");
  }
  for (const MatrixPanel& p : spec.panels) {
    bool ok = int(p.counts.size()) == nr;
    for (const auto& row : p.counts) ok = ok && int(row.size()) == nc;
    if (!ok) {
      throw InvalidArgument(
          "write_matrix_plot",
          "panel '" + p.title + "' is not " + std::to_string(nr) + "×" + std::to_string(nc),
          "give one count per row and column");
    }
  }
  constexpr int kCell = 80, kLeftLabels = 150, kGap = 50, kTopTitle = 60, kHeader = 70;
  const int panel_w = kLeftLabels + nc * kCell;
  const int width = kGap + int(spec.panels.size()) * (panel_w + kGap);
  const int height = kTopTitle + kHeader + nr * kCell + 60;
  cv::Mat img(height, width, CV_8UC3, cv::Scalar(255, 255, 255));
  text(img, spec.title, {width / 2, 30}, 0.7, true);
  for (std::size_t pi = 0; pi < spec.panels.size(); ++pi) {
    const MatrixPanel& p = spec.panels[pi];
    const int x0 = kGap + int(pi) * (panel_w + kGap) + kLeftLabels, y0 = kTopTitle + kHeader;
    int total = 0;
    for (const auto& row : p.counts) {
      for (int c : row) total += c;
    }
    text(img, p.title, {x0 + nc * kCell / 2, kTopTitle + 10}, 0.5, true);
    text(img, spec.column_label, {x0 + nc * kCell / 2, kTopTitle + 32}, 0.45, true);
    for (int c = 0; c < nc; ++c) {
      text(img, spec.columns[std::size_t(c)], {x0 + c * kCell + kCell / 2, y0 - 10}, 0.45, true);
    }
    text(img, spec.row_label, {x0 - kLeftLabels + 4, y0 - 10}, 0.45);
    for (int r = 0; r < nr; ++r) {
      text(img, spec.rows[std::size_t(r)], {x0 - kLeftLabels + 20, y0 + r * kCell + kCell / 2 + 5},
           0.5);
      for (int c = 0; c < nc; ++c) {
        const int n = p.counts[std::size_t(r)][std::size_t(c)];
        const double share = total > 0 ? double(n) / total : 0;
        const int shade = int(std::lround(255 - 170 * std::sqrt(share)));
        const cv::Rect cell(x0 + c * kCell, y0 + r * kCell, kCell, kCell);
        cv::rectangle(img, cell, cv::Scalar(255, shade, shade), cv::FILLED);
        cv::rectangle(img, cell, cv::Scalar(150, 150, 150), 1);
        text(img, std::to_string(n), {cell.x + kCell / 2, cell.y + kCell / 2 + 6}, 0.6, true);
      }
    }
    text(img, "n = " + std::to_string(total), {x0 + nc * kCell / 2, y0 + nr * kCell + 30}, 0.45,
         true);
  }
  write_image(path, image_from_bgr(img), force);
}

}  // namespace vkjr2::cli
