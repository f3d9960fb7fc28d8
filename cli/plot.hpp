// Line plots as PNG for the reports (ROC, CMC, FNIR–FPIR): axes with ticks
// and labels, a linear or log10 x axis, a grid, a title and a legend.
#pragma once

#include <filesystem>
#include <string>
#include <utility>
#include <vector>

namespace vkjr2::cli {

struct PlotSeries {
  std::string label;
  std::vector<std::pair<double, double>> points;  // (x, y), drawn in order as steps or lines
};

struct PlotSpec {
  std::string title, x_label, y_label;
  bool log_x = false;
  // log_x with x_min ≤ 0: the decade below the smallest positive x of the series.
  double x_min = 0, x_max = 1, y_min = 0, y_max = 1;
  bool steps = false;       // draw as a staircase (ROC, DET) instead of straight lines
  bool legend_top = false;  // the legend in the top right corner (else bottom right)
  std::vector<PlotSeries> series;
};

// Writes the plot (1000×700 px) atomically; refuses to replace a file unless force.
void write_plot(const std::filesystem::path& path, const PlotSpec& spec, bool force);

// Count matrices side by side (a confusion matrix per panel): each cell its
// count, shaded by its share of the panel's total.
struct MatrixPanel {
  std::string title;
  std::vector<std::vector<int>> counts;  // [row][column]
};
struct MatrixSpec {
  std::string title, row_label, column_label;
  std::vector<std::string> rows, columns;  // the categories' names
  std::vector<MatrixPanel> panels;
};
// Writes the matrices atomically; refuses to replace a file unless force.
// Throws InvalidArgument when a panel's counts do not match the categories.
void write_matrix_plot(const std::filesystem::path& path, const MatrixSpec& spec, bool force);

}  // namespace vkjr2::cli
