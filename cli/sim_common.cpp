#include "sim_common.hpp"

#include <vkjr2/runtime/error.hpp>
#include <vkjr2/sim/p2s_blur_model.hpp>

#include <algorithm>
#include <cmath>
#include <exception>
#include <iterator>

#include "checks.hpp"

namespace vkjr2::cli {

void add_path_options(CLI::App* cmd, PathArgs& a) {
  cmd->add_option("--preset", a.preset, "Turbulence preset")
      ->default_val("moderate")
      ->check(CLI::IsMember({"weak", "moderate", "strong"}));
  cmd->add_option("--config", a.config,
                  "JSON or YAML (.yaml/.yml) parameter file (docs/sim.md §1); overrides --preset");
  CLI::Option* cn2 = cmd->add_option("--cn2", a.cn2, "Uniform Cn² along the path, m^(-2/3)")
                         ->check(positive_up_to(1e-9));
  cmd->add_option("--r0", a.r0,
                  "Fried parameter r0 in metres at the first wavelength (instead of --cn2)")
      ->check(positive_up_to(100))
      ->excludes(cn2);
  cmd->add_option("--range", a.range, "Path length L in metres")->check(positive_up_to(1e6));
  cmd->add_option("--wavelengths", a.wavelengths,
                  "Wavelength(s) in nm: one for all channels, one per channel (R,G,B), or 'rgb' "
                  "for 610,525,465 (the shipped blur models' set)")
      ->check(CLI::Validator(
          [](const std::string& v) {
            try {
              parse_wavelengths_nm(v, "--wavelengths");
              return std::string();
            } catch (const Error& e) {
              return e.problem() + " (" + e.fix() + ")";
            }
          },
          "NM[,NM,NM]|rgb"));
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
      throw UsageError(option, "'" + text + "' is not a list of wavelengths in nm",
                       "write e.g. 525, or 610,525,465 (one per channel), or rgb");
    }
    if (nm < 100 || nm > 20000) {
      throw UsageError(option, item + " nm is outside 100..20000 nm",
                       "give the wavelength in nanometres, e.g. 525");
    }
    out.push_back(nm * 1e-9);
    start = comma + 1;
  }
  return out;
}

sim::Params params_from_args(const PathArgs& a) {
  if (!a.config.empty()) check_input_file(a.config, "--config");
  sim::Params p = a.config.empty() ? sim::preset(a.preset) : sim::load_params(a.config);
  if (!a.wavelengths.empty()) {
    std::vector<double> w = parse_wavelengths_nm(a.wavelengths, "--wavelengths");
    if (w.size() != 1 && w.size() != 3) {
      throw UsageError("--wavelengths", std::to_string(w.size()) + " wavelengths given",
                       "give one for every channel, or three (R,G,B), e.g. 610,525,465");
    }
    sim::set_wavelengths(p, std::move(w));
  }
  if (a.range) p.path.range_m = *a.range;
  if (a.cn2 && a.r0) throw UsageError("--cn2/--r0", "give one turbulence strength, not both");
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

namespace {

// The option (or the config file) a sim::Params field came from.
std::string option_of(const PathArgs& a, const std::string& field) {
  if (field.starts_with("path.r0") && a.r0) return "--r0";
  if (field.starts_with("path.cn2") && a.cn2) return "--cn2";
  if (field.starts_with("path.range_m") && a.range) return "--range";
  if (field.starts_with("optics.wavelengths_m") && !a.wavelengths.empty()) return "--wavelengths";
  return a.config.empty() ? "--preset" : "--config " + a.config;
}

// sim::Params' messages name its fields ("path.r0_m is -1 but must be > 0");
// the user is told which option it was.
[[noreturn]] void rethrow_as_usage(const PathArgs& a, const InvalidArgument& e) {
  std::string problem = e.problem();
  const std::size_t space = problem.find(' ');
  const std::string field = problem.substr(0, space);
  if (field.find('.') != std::string::npos && field.find('_') != std::string::npos) {
    const std::string option = option_of(a, field);
    if (!option.starts_with("--config") && !option.starts_with("--preset")) {
      problem = problem.substr(space + 1);  // "--r0: is -1 ..." reads as "--r0 is -1 ..."
      throw UsageError(option, "the value " + problem, e.fix());
    }
    throw UsageError(option, field + " " + problem.substr(space + 1), e.fix());
  }
  // Derived limits (D/r0, Rytov): the options together.
  std::string given;
  if (!a.config.empty()) given += " --config " + a.config;
  if (a.config.empty()) given += " --preset " + a.preset;
  if (a.r0) given += " --r0";
  if (a.cn2) given += " --cn2";
  if (a.range) given += " --range";
  if (!a.wavelengths.empty()) given += " --wavelengths";
  throw UsageError("", "with" + given + ": " + problem, e.fix());
}

}  // namespace

sim::Params params_for_image(const PathArgs& a, int height, int width) {
  sim::Params p = params_from_args(a);
  p.image = {height, width, a.grey ? 1 : 3, 1};
  if (p.optics.wavelengths_m.size() > 1 && int(p.optics.wavelengths_m.size()) != p.image.channels) {
    throw UsageError(a.wavelengths.empty() ? "--config" : "--wavelengths",
                     std::to_string(p.optics.wavelengths_m.size()) + " wavelengths for a " +
                         std::to_string(p.image.channels) + "-channel image",
                     a.grey ? "give one wavelength for --grey"
                            : "give one wavelength, or one per channel (R,G,B)");
  }
  try {
    (void)sim::derive(p);  // validates, then the derived limits (D/r0, Rytov)
  } catch (const InvalidArgument& e) {
    rethrow_as_usage(a, e);
  }
  return p;
}

std::vector<std::shared_ptr<const sim::BlurModel>> load_blur_models(
    const Device& device, const std::vector<std::string>& paths) {
  if (paths.empty()) return sim::load_shipped_blur_models(device);
  std::vector<std::shared_ptr<const sim::BlurModel>> models;
  for (const auto& path : paths) models.push_back(sim::load_blur_model(device, path));
  return models;
}

void check_blur_models(const PathArgs& a, const sim::Params& params,
                       const std::vector<std::shared_ptr<const sim::BlurModel>>& models) {
  const sim::Derived d = sim::derive(params);
  for (int c = 0; c < params.image.channels; ++c) {
    const double nyquist = d.channels[std::size_t(c)].nyquist;
    if (sim::blur_model_for(models, nyquist) != nullptr) continue;
    std::string offered;
    for (const auto& m : models) offered += (offered.empty() ? "" : ", ") + readable(m->nyquist());
    const std::string made = "p2s_ch" + std::to_string(c) + ".safetensors";
    const std::string how = a.config.empty()
                                ? "--preset " + a.preset + " --wavelength " +
                                      readable(d.channels[std::size_t(c)].wavelength_m * 1e9)
                                : "--config " + a.config + " --channel " + std::to_string(c);
    throw Error(a.config.empty() ? "--wavelengths" : "--config",
                "channel " + std::to_string(c) + " (" +
                    readable(d.channels[std::size_t(c)].wavelength_m * 1e9) +
                    " nm) samples the PSF at Nyquist ratio " + readable(nyquist) +
                    ", and no blur model was made for that sampling (the ones given: " + offered +
                    ")",
                std::string("make one for these optics with `vkjr2 sim-train ")
                    .append(made)
                    .append(" ")
                    .append(how)
                    .append("` and pass it with --blur-model ")
                    .append(made)
                    .append(" (or simulate with --no-blur)"));
  }
}

}  // namespace vkjr2::cli
