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

}  // namespace vkjr2::cli
