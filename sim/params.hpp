// Physical parameters of a turbulent imaging path and the quantities derived
// from them (r0, D/r0, isoplanatic angle, Rytov number, sampling). The
// conventions and formulas are derived in docs/sim.md.
//
// Path coordinate: z runs from the scene (z = 0) to the aperture (z = L).
// Every scene point is a point source at range L, so the wave reaching the
// aperture is spherical and the spherical-wave weightings apply by default.
#pragma once

#include <vkjr2/sim/zernike.hpp>

#include <filesystem>
#include <string>
#include <string_view>
#include <vector>

namespace vkjr2::sim {

// Which wave r0 is computed for. spherical: a scene at finite range L (imaging
// along a horizontal path; the default). plane: a source at infinity.
enum class WaveModel { spherical, plane };

// How the turbulence strength is given.
enum class Strength {
  r0,            // Path::r0_m at Path::r0_wavelength_m; Cn² taken uniform along the path
  constant_cn2,  // Path::cn2, uniform along the path
  cn2_profile,   // Path::cn2_z_m / Path::cn2_profile, piecewise linear in z
};

// How the detector sampling is given.
enum class Sampling {
  pixel_pitch,  // Optics::pixel_pitch_m
  field_width,  // Optics::field_width_m: object-plane width of the image at range L
};

struct Optics {
  double aperture_m = 0.2;      // D
  double focal_length_m = 1.6;  // f
  // One wavelength for all channels, or one per channel (e.g. R, G, B).
  std::vector<double> wavelengths_m{525e-9};
  Sampling sampling = Sampling::pixel_pitch;
  double pixel_pitch_m = 3.45e-6;  // used when sampling == pixel_pitch
  double field_width_m = 0.0;      // used when sampling == field_width
};

struct Path {
  double range_m = 1000.0;  // L
  Strength strength = Strength::constant_cn2;
  WaveModel wave = WaveModel::spherical;
  double r0_m = 0.0;             // Strength::r0
  double r0_wavelength_m = 0.0;  // wavelength r0_m holds at; 0 = Optics::wavelengths_m[0]
  double cn2 = 4e-15;            // Strength::constant_cn2, in m^(-2/3)
  // Strength::cn2_profile: z strictly increasing in [0, L] (0 = scene); Cn² is
  // linear between samples and held constant beyond the first and last.
  std::vector<double> cn2_z_m;
  std::vector<double> cn2_profile;
};

struct ImageShape {
  int height = 256;
  int width = 256;
  int channels = 1;
  int batch = 1;
};

// Defaults: the "moderate" preset.
struct Params {
  Optics optics;
  Path path;
  ImageShape image;
  int zernike_modes = 36;  // Noll j = 2..zernike_modes are simulated (piston excluded)
};

// Per colour channel.
struct ChannelDerived {
  double wavelength_m = 0;
  double r0_m = 0;                   // Fried parameter at this wavelength
  double d_over_r0 = 0;              // D / r0
  double isoplanatic_angle_rad = 0;  // θ0
  double isoplanatic_angle_px = 0;   // θ0 / IFOV
  double rytov = 0;                  // spherical-wave log-amplitude variance σ_χ²
  double nyquist = 0;                // λ f / (2 D p): 1 = Nyquist sampled, < 1 aliased
  double tilt_std_rad = 0;           // one-axis Z-tilt angle, standard deviation
  double tilt_std_px = 0;            // the same in pixels
  double seeing_fwhm_px = 0;         // long-exposure FWHM ≈ 0.98 λ / r0, in pixels
};

struct Derived {
  double pixel_pitch_m = 0;      // from the pitch or the field width
  double ifov_rad = 0;           // p / f
  double object_pixel_m = 0;     // L p / f: a pixel's footprint at range L
  double field_width_m = 0;      // width · object_pixel_m
  double cn2_path_integral = 0;  // ∫ Cn² dz over the path, m^(1/3)
  std::vector<ChannelDerived> channels;
  // Out-of-model conditions a caller should print (the simulator still runs).
  std::vector<std::string> warnings;
};

// Thresholds of the model (docs/sim.md, "Validity").
inline constexpr double kRytovWarn = 0.25;    // σ_χ² above: scintillation not negligible
inline constexpr double kRytovMax = 2.5;      // σ_χ² above: saturated, phase-only model void
inline constexpr double kDOverR0Warn = 20.0;  // the Zernike modes leave too much residual phase
inline constexpr double kDOverR0Max = 100.0;
inline constexpr double kNyquistWarn = 0.5;
inline constexpr int kMaxImageSide = 65536;

// Throws InvalidArgument naming the field and the fix on any invalid value
// (non-positive sizes, NaN, negative Cn², inconsistent profile, …).
void validate(const Params& params);

// Validates, then derives. Throws InvalidArgument when the parameters are
// absurd for this model (D/r0 > kDOverR0Max, σ_χ² > kRytovMax); out-of-model
// but usable conditions go to Derived::warnings.
Derived derive(const Params& params);

// Detector pixel pitch: Optics::pixel_pitch_m, or from the field width
// (field_width_m · f / (L · width)). Validates first.
double pixel_pitch_m(const Params& params);

// Wavelength of channel c (the single wavelength when only one is given).
double channel_wavelength_m(const Params& params, int channel);
// Replaces optics.wavelengths_m and keeps the turbulence: an r0 given at the
// first wavelength (Strength::r0, r0_wavelength_m = 0) is pinned to the
// wavelength it was given at. Not validated (validate() does that).
void set_wavelengths(Params& params, std::vector<double> wavelengths_m);

// The path integrals of Cn² with the weightings used by derive(), for the
// parameters' path (with Strength::r0 the equivalent uniform Cn² at
// r0_wavelength_m): ∫Cn² dz, ∫Cn² (z/L)^(5/3) dz, ∫Cn² (1 − z/L)^(5/3) dz,
// ∫Cn² (1 − z/L)^(5/6) z^(5/6) dz.
struct PathIntegrals {
  double plain = 0;
  double spherical = 0;
  double isoplanatic = 0;
  double rytov = 0;
};
PathIntegrals path_integrals(const Params& params);

// Cn²(z) in m^(−2/3) at distance z_m from the scene, as derive() sees it:
// the profile (linear between samples, constant beyond), the constant Cn², or
// the uniform Cn² equivalent to a given r0.
double cn2_at(const Params& params, double z_m);

// Named presets at L = 1 km: "weak", "moderate", "strong" (D/r0 ≈ 1.5, 3, 6 at
// 525 nm; numbers in docs/sim.md).
Params preset(std::string_view name);
std::vector<std::string> preset_names();

// One line for the command runner, e.g.
// "L=1000 m D=0.2 m f=1.6 m λ=525 nm r0=6.7 cm D/r0=3.0 θ0=… Rytov=… Nyquist=0.61 256×256×1 ×1".
std::string summary(const Params& params, const Derived& derived);

// JSON config (YAML below: the same keys). Keys (all optional; absent keys keep the preset's
// value):
// {"preset": "moderate",
//  "optics": {"aperture_m", "focal_length_m", "wavelengths_m": [..] or number,
//             "pixel_pitch_m" | "field_width_m"},
//  "path": {"range_m", "wave": "spherical"|"plane",
//           "r0_m" (+ "r0_wavelength_m") | "cn2" | "cn2_profile": {"z_m": [..], "cn2": [..]}},
//  "image": {"height", "width", "channels", "batch"},
//  "zernike_modes"}
// Unknown keys, wrong types and conflicting keys are errors naming the key.
// Several wavelengths and no image.channels: the image gets one channel per wavelength.
// source names the text in messages (a file name).
Params params_from_json(std::string_view text, std::string_view source = "config");
std::string params_to_json(const Params& params);
// YAML config: the same keys, semantics and errors (the document is read as
// the JSON value it denotes, YAML 1.2 core schema: quoted scalars are
// strings, plain ones null/bool/int/float by their spelling), plus a
// duplicated key is an error. Throws InvalidArgument naming source for
// malformed YAML (with line and column).
Params params_from_yaml(std::string_view text, std::string_view source = "config");
std::string params_to_yaml(const Params& params);
// By extension (case-insensitive): .yaml or .yml is YAML, anything else JSON.
Params load_params(const std::filesystem::path& path);
// YAML for .yaml/.yml, else JSON; written to a temporary name, then renamed.
void save_params(const Params& params, const std::filesystem::path& path);

}  // namespace vkjr2::sim
