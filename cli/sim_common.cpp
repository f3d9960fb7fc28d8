#include "sim_common.hpp"

#include <vkjr2/runtime/error.hpp>
#include <vkjr2/sim/blur_model.hpp>

#include <algorithm>
#include <cmath>
#include <exception>
#include <iterator>

namespace vkjr2::cli {

void add_path_options(CLI::App* cmd, PathArgs& a) {
  cmd->add_option("--preset", a.preset, "Turbulence preset")
      ->default_val("moderate")
      ->check(CLI::IsMember({"weak", "moderate", "strong"}));
  cmd->add_option("--config", a.config,
                  "JSON or YAML (.yaml/.yml) parameter file (docs/sim.md §1); overrides --preset");
  cmd->add_option("--cn2", a.cn2, "Uniform Cn² along the path, m^(-2/3)");
  cmd->add_option("--r0", a.r0,
                  "Fried parameter r0 in metres at the first wavelength (instead of --cn2)");
  cmd->add_option("--range", a.range, "Path length L in metres");
  cmd->add_option("--wavelengths", a.wavelengths,
                  "Wavelength(s) in nm: one for all channels, one per channel (R,G,B), or 'rgb' "
                  "for 610,525,465 (the shipped blur models' set)")
      ->check([](const std::string& v) {
        try {
          parse_wavelengths_nm(v, "--wavelengths");
          return std::string();
        } catch (const Error& e) {
          return std::string(e.what());
        }
      });
  cmd->add_flag("--grey", a.grey, "Simulate one grey channel instead of RGB");
}

std::vector<double> parse_wavelengths_nm(const std::string& text, const std::string& option) {
  if (text == "rgb") return {std::begin(sim::kRgbWavelengthsM), std::end(sim::kRgbWavelengthsM)};
  std::vector<double> out;
  std::size_t start = 0;
  while (start <= text.size()) {
    const std::size_t comma = std::min(text.find(',', start), text.size());
    const std::string item = text.substr(start, comma - start);
    std::size_t used = 0;
    double nm = 0;
    try {
      nm = std::stod(item, &used);
    } catch (const std::exception&) {
      used = 0;
    }
    if (item.empty() || used != item.size() || !std::isfinite(nm) || nm <= 0) {
      throw InvalidArgument(option, "'" + text + "' is not a list of wavelengths in nm",
                            "write e.g. 525, or 610,525,465 (one per channel), or rgb");
    }
    if (nm < 100 || nm > 20000) {
      throw InvalidArgument(option, item + " nm is outside 100..20000 nm",
                            "give the wavelength in nanometres, e.g. 525");
    }
    out.push_back(nm * 1e-9);
    start = comma + 1;
  }
  return out;
}

sim::Params params_from_args(const PathArgs& a) {
  sim::Params p = a.config.empty() ? sim::preset(a.preset) : sim::load_params(a.config);
  if (!a.wavelengths.empty())
    sim::set_wavelengths(p, parse_wavelengths_nm(a.wavelengths, "--wavelengths"));
  if (a.range) p.path.range_m = *a.range;
  if (a.cn2 && a.r0) throw InvalidArgument("--cn2/--r0", "give one turbulence strength, not both");
  if (a.cn2) {
    p.path.strength = sim::Strength::constant_cn2;
    p.path.cn2 = *a.cn2;
  }
  if (a.r0) {
    p.path.strength = sim::Strength::r0;
    p.path.r0_m = *a.r0;
    p.path.r0_wavelength_m = p.optics.wavelengths_m.front();
  }
  return p;
}

sim::Params params_for_image(const PathArgs& a, int height, int width) {
  sim::Params p = params_from_args(a);
  p.image = {height, width, a.grey ? 1 : 3, 1};
  if (p.optics.wavelengths_m.size() > 1 && int(p.optics.wavelengths_m.size()) != p.image.channels) {
    throw InvalidArgument("params",
                          "the config gives " + std::to_string(p.optics.wavelengths_m.size()) +
                              " wavelengths for a " + std::to_string(p.image.channels) +
                              "-channel image",
                          a.grey ? "give one wavelength for --grey"
                                 : "give one wavelength, or one per channel (R,G,B)");
  }
  return p;
}

std::vector<float> to_planes(const Image& img, int channels) {
  const std::size_t hw = std::size_t(img.shape[0] * img.shape[1]);
  std::vector<float> out(hw * std::size_t(channels));
  for (std::size_t i = 0; i < hw; ++i) {
    const float* px = &img.values[i * 3];
    if (channels == 1) {
      out[i] = (px[0] + px[1] + px[2]) / (3 * 255.f);
    } else {
      for (int c = 0; c < 3; ++c) out[std::size_t(c) * hw + i] = px[c] / 255.f;
    }
  }
  return out;
}

Image from_planes(const std::vector<float>& planes, int channels, std::int64_t height,
                  std::int64_t width) {
  Image img;
  img.shape = {height, width, 3};
  const std::size_t hw = std::size_t(height * width);
  img.values.resize(hw * 3);
  for (std::size_t i = 0; i < hw; ++i) {
    for (int c = 0; c < 3; ++c) {
      const float v = planes[(channels == 1 ? 0 : std::size_t(c)) * hw + i];
      img.values[i * 3 + std::size_t(c)] = std::clamp(v, 0.f, 1.f) * 255.f;
    }
  }
  return img;
}

}  // namespace vkjr2::cli
