// What the turbulence commands (simulate, wave, bench sim) share: the path
// and optics options, and images as NCHW planes.
#pragma once

#include <vkjr2/sim/p2s_blur_model.hpp>
#include <vkjr2/sim/params.hpp>

#include <CLI/CLI.hpp>

#include <memory>
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
// The parameters for one height × width image (RGB, or grey with --grey),
// validated and derived (sim::derive) so that a mistake is found before any
// work: UsageError naming the option the user typed (--r0, --cn2, --range,
// --wavelengths, --config) for parameters that cannot be simulated; Error
// for a config file that cannot be read.
sim::Params params_for_image(const PathArgs& a, int height, int width);
// --preset/--config with --range, --cn2, --r0 and --wavelengths applied (image shape untouched).
sim::Params params_from_args(const PathArgs& a);
// --blur-model FILE...: the models at these paths, or the shipped ones
// (sim::load_shipped_blur_models) when none is given.
std::vector<std::shared_ptr<const sim::BlurModel>> load_blur_models(
    const Device& device, const std::vector<std::string>& paths);
// Throws Error (exit code 1: a model is missing, the options are fine), with
// the command that makes one, when a channel has no blur model made for its
// sampling (a --config with its own optics, another wavelength).
void check_blur_models(const PathArgs& a, const sim::Params& params,
                       const std::vector<std::shared_ptr<const sim::BlurModel>>& models);
// "rgb" → sim::kRgbWavelengthsM; "610,525,465" → metres. Throws InvalidArgument naming the option.
std::vector<double> parse_wavelengths_nm(const std::string& text, const std::string& option);

}  // namespace vkjr2::cli
