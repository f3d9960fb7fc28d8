// What the turbulence commands (simulate, wave, bench sim) share: the path
// and optics options, and images as NCHW planes.
#pragma once

#include <vkjr2/sim/params.hpp>

#include <CLI/CLI.hpp>

#include <optional>
#include <string>
#include <vector>

#include "media.hpp"

namespace vkjr2::cli {

struct PathArgs {
  std::string preset = "moderate", config, wavelengths;
  std::optional<double> cn2, r0, range;
  bool grey = false;
};

// --preset, --config, --cn2, --r0, --range, --wavelengths, --grey.
void add_path_options(CLI::App* cmd, PathArgs& a);
// The parameters for one height × width image (RGB, or grey with --grey).
sim::Params params_for_image(const PathArgs& a, int height, int width);
// --preset/--config with --range, --cn2, --r0 and --wavelengths applied (image shape untouched).
sim::Params params_from_args(const PathArgs& a);
// "rgb" → sim::kRgbWavelengthsM; "610,525,465" → metres. Throws InvalidArgument naming the option.
std::vector<double> parse_wavelengths_nm(const std::string& text, const std::string& option);

// HWC RGB 0..255 → CHW 0..1 (grey: the mean of R, G, B).
std::vector<float> to_planes(const Image& img, int channels);
// CHW 0..1 → HWC RGB 0..255 (clamped; grey repeated).
Image from_planes(const std::vector<float>& planes, int channels, std::int64_t height,
                  std::int64_t width);

}  // namespace vkjr2::cli
