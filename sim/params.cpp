#include <vkjr2/runtime/error.hpp>
#include <vkjr2/runtime/host_tensor.hpp>
#include <vkjr2/sim/noll.hpp>
#include <vkjr2/sim/params.hpp>
#include <vkjr2/sim/quadrature.hpp>

#include <nlohmann/json.hpp>

#include <algorithm>
#include <array>
#include <cctype>
#include <cmath>
#include <cstdio>
#include <limits>
#include <numbers>
#include <string>
#include <utility>

namespace vkjr2::sim {
namespace {

using json = nlohmann::json;

constexpr const char* kOp = "sim::Params";

std::string num(double v) {
  char buf[64];
  std::snprintf(buf, sizeof buf, "%.6g", v);
  return buf;
}

[[noreturn]] void bad(const std::string& field, const std::string& problem,
                      const std::string& fix) {
  throw InvalidArgument(kOp, field + " " + problem, fix);
}

void require_positive(double v, const std::string& field, const std::string& fix) {
  if (!std::isfinite(v)) bad(field, "is " + num(v) + ", not a finite number", fix);
  if (v <= 0) bad(field, "is " + num(v) + " but must be > 0", fix);
}

double wavenumber(double wavelength_m) { return 2 * std::numbers::pi / wavelength_m; }

// Cn² along the path as a function of z (0 = scene, L = aperture).
struct Profile {
  std::vector<double> z;
  std::vector<double> c;
  double at(double zz) const {
    if (z.size() == 1 || zz <= z.front()) return c.front();
    if (zz >= z.back()) return c.back();
    const auto it = std::upper_bound(z.begin(), z.end(), zz);
    const auto i = static_cast<std::size_t>(it - z.begin());
    const double t = (zz - z[i - 1]) / (z[i] - z[i - 1]);
    return c[i - 1] + t * (c[i] - c[i - 1]);
  }
};

// r0^(−5/3) = coeff · k² · I where I is the path integral with the model's weighting.
constexpr double kPlaneR0Coeff = 0.423;  // Fried 1966; Andrews & Phillips (2005) eq. 6.60

double weighted_integral(const PathIntegrals& in, WaveModel wave) {
  return wave == WaveModel::spherical ? in.spherical : in.plain;
}

double r0_from(double integral, double wavelength_m) {
  if (integral <= 0) return std::numeric_limits<double>::infinity();
  const double k = wavenumber(wavelength_m);
  return std::pow(kPlaneR0Coeff * k * k * integral, -3.0 / 5.0);
}

PathIntegrals integrate(const Profile& profile, double range_m) {
  static const GaussLegendre gl(8);
  // Breakpoints: the profile samples plus a uniform grid fine enough for the
  // endpoint behaviour of z^(5/6) and (1 − z/L)^(5/6) (relative error < 1e-8).
  std::vector<double> cuts;
  constexpr int kUniform = 256;
  for (int i = 0; i <= kUniform; ++i) cuts.push_back(range_m * i / kUniform);
  for (double zz : profile.z)
    if (zz > 0 && zz < range_m) cuts.push_back(zz);
  std::sort(cuts.begin(), cuts.end());
  cuts.erase(std::unique(cuts.begin(), cuts.end()), cuts.end());
  PathIntegrals out;
  for (std::size_t s = 0; s + 1 < cuts.size(); ++s) {
    const double a = cuts[s];
    const double b = cuts[s + 1];
    const double half = (b - a) / 2;
    for (std::size_t i = 0; i < gl.x.size(); ++i) {
      const double zz = a + half * (gl.x[i] + 1);
      const double w = half * gl.w[i] * profile.at(zz);
      const double u = zz / range_m;
      out.plain += w;
      out.spherical += w * std::pow(u, 5.0 / 3.0);
      out.isoplanatic += w * std::pow(1 - u, 5.0 / 3.0);
      out.rytov += w * std::pow(1 - u, 5.0 / 6.0) * std::pow(zz, 5.0 / 6.0);
    }
  }
  return out;
}

Profile profile_of(const Params& p) {
  const Path& path = p.path;
  switch (path.strength) {
    case Strength::constant_cn2:
      return {{0.0}, {path.cn2}};
    case Strength::cn2_profile:
      return {path.cn2_z_m, path.cn2_profile};
    case Strength::r0: {
      // The uniform Cn² that gives r0_m at r0_wavelength_m under the wave model.
      const double lambda =
          path.r0_wavelength_m > 0 ? path.r0_wavelength_m : p.optics.wavelengths_m.front();
      const double k = wavenumber(lambda);
      const double weight = path.wave == WaveModel::spherical ? 3.0 / 8.0 : 1.0;  // ∫(z/L)^(5/3)
      const double cn2 =
          std::pow(path.r0_m, -5.0 / 3.0) / (kPlaneR0Coeff * k * k * weight * path.range_m);
      return {{0.0}, {cn2}};
    }
  }
  return {{0.0}, {0.0}};
}

}  // namespace

double cn2_at(const Params& params, double z_m) { return profile_of(params).at(z_m); }

double channel_wavelength_m(const Params& params, int channel) {
  const auto& w = params.optics.wavelengths_m;
  if (channel < 0 || channel >= params.image.channels)
    throw InvalidArgument("sim::channel_wavelength_m",
                          "channel " + std::to_string(channel) + " is outside 0.." +
                              std::to_string(params.image.channels - 1),
                          "pass a channel index below image.channels");
  if (w.empty()) bad("optics.wavelengths_m", "is empty", "give one wavelength or one per channel");
  return w.size() == 1 ? w.front() : w[static_cast<std::size_t>(channel)];
}

void set_wavelengths(Params& params, std::vector<double> wavelengths_m) {
  if (params.path.strength == Strength::r0 && params.path.r0_wavelength_m == 0 &&
      !params.optics.wavelengths_m.empty())
    params.path.r0_wavelength_m = params.optics.wavelengths_m.front();
  params.optics.wavelengths_m = std::move(wavelengths_m);
}

void validate(const Params& p) {
  const Optics& o = p.optics;
  require_positive(o.aperture_m, "optics.aperture_m",
                   "give the aperture diameter in metres, e.g. 0.2");
  require_positive(o.focal_length_m, "optics.focal_length_m",
                   "give the focal length in metres, e.g. 1.6");
  if (o.wavelengths_m.empty())
    bad("optics.wavelengths_m", "is empty", "give one wavelength (e.g. 525e-9) or one per channel");
  for (std::size_t i = 0; i < o.wavelengths_m.size(); ++i) {
    const double w = o.wavelengths_m[i];
    const std::string field = "optics.wavelengths_m[" + std::to_string(i) + "]";
    require_positive(w, field, "give the wavelength in metres, e.g. 525e-9");
    if (w < 1e-8 || w > 1e-4)
      bad(field, "is " + num(w) + " m, outside 10 nm .. 100 µm",
          "wavelengths are in metres: 525 nm is 525e-9");
  }
  if (o.sampling == Sampling::pixel_pitch)
    require_positive(o.pixel_pitch_m, "optics.pixel_pitch_m",
                     "give the detector pixel pitch in metres, e.g. 3.45e-6");
  else
    require_positive(o.field_width_m, "optics.field_width_m",
                     "give the object-plane width of the image at the range in metres");

  const ImageShape& im = p.image;
  auto check_int = [](int v, const std::string& field, int hi) {
    if (v <= 0 || v > hi)
      bad(field, "is " + std::to_string(v) + " but must be in 1.." + std::to_string(hi),
          "give a positive size");
  };
  check_int(im.height, "image.height", kMaxImageSide);
  check_int(im.width, "image.width", kMaxImageSide);
  check_int(im.channels, "image.channels", 64);
  check_int(im.batch, "image.batch", 1 << 20);
  if (o.wavelengths_m.size() != 1 &&
      o.wavelengths_m.size() != static_cast<std::size_t>(im.channels))
    bad("optics.wavelengths_m",
        "has " + std::to_string(o.wavelengths_m.size()) + " entries for " +
            std::to_string(im.channels) + " image.channels",
        "give one wavelength for all channels or exactly one per channel");
  if (p.zernike_modes < 3 || p.zernike_modes > kMaxZernikeModes)
    bad("zernike_modes",
        "is " + std::to_string(p.zernike_modes) + " but must be in 3.." +
            std::to_string(kMaxZernikeModes),
        "use 36 (Noll j = 2..36) unless you know why not");

  const Path& path = p.path;
  require_positive(path.range_m, "path.range_m", "give the distance to the scene in metres");
  switch (path.strength) {
    case Strength::r0:
      require_positive(path.r0_m, "path.r0_m", "give the Fried parameter in metres, e.g. 0.05");
      if (path.r0_wavelength_m != 0)
        require_positive(path.r0_wavelength_m, "path.r0_wavelength_m",
                         "give the wavelength r0_m holds at, or 0 for optics.wavelengths_m[0]");
      break;
    case Strength::constant_cn2:
      if (!std::isfinite(path.cn2)) bad("path.cn2", "is " + num(path.cn2), "give a finite Cn²");
      if (path.cn2 < 0)
        bad("path.cn2", "is " + num(path.cn2) + " but Cn² cannot be negative",
            "give Cn² in m^(-2/3), typically 1e-17 (weak) .. 1e-13 (very strong)");
      break;
    case Strength::cn2_profile: {
      const auto& z = path.cn2_z_m;
      const auto& c = path.cn2_profile;
      if (z.empty() || z.size() != c.size())
        bad("path.cn2_profile",
            "has " + std::to_string(c.size()) + " values for " + std::to_string(z.size()) +
                " positions (path.cn2_z_m)",
            "give one Cn² value per position, at least one");
      for (std::size_t i = 0; i < z.size(); ++i) {
        const std::string zi = "path.cn2_z_m[" + std::to_string(i) + "]";
        const std::string ci = "path.cn2_profile[" + std::to_string(i) + "]";
        if (!std::isfinite(z[i]) || z[i] < 0 || z[i] > path.range_m)
          bad(zi, "is " + num(z[i]) + ", outside the path 0.." + num(path.range_m) + " m",
              "positions run from the scene (0) to the aperture (path.range_m)");
        if (i > 0 && z[i] <= z[i - 1])
          bad(zi, "is not greater than the previous position " + num(z[i - 1]),
              "list positions in strictly increasing order");
        if (!std::isfinite(c[i])) bad(ci, "is " + num(c[i]), "give a finite Cn²");
        if (c[i] < 0)
          bad(ci, "is " + num(c[i]) + " but Cn² cannot be negative", "give Cn² ≥ 0 in m^(-2/3)");
      }
      break;
    }
  }
}

double pixel_pitch_m(const Params& p) {
  validate(p);
  const Optics& o = p.optics;
  return o.sampling == Sampling::pixel_pitch
             ? o.pixel_pitch_m
             : o.field_width_m * o.focal_length_m / (p.path.range_m * p.image.width);
}

PathIntegrals path_integrals(const Params& params) {
  validate(params);
  return integrate(profile_of(params), params.path.range_m);
}

Derived derive(const Params& p) {
  const PathIntegrals in = path_integrals(p);
  const Optics& o = p.optics;
  const double L = p.path.range_m;
  Derived d;
  d.pixel_pitch_m = pixel_pitch_m(p);
  d.ifov_rad = d.pixel_pitch_m / o.focal_length_m;
  d.object_pixel_m = L * d.ifov_rad;
  d.field_width_m = d.object_pixel_m * p.image.width;
  d.cn2_path_integral = in.plain;

  const double tilt_var_unit = noll_covariance(2, 2) * std::pow(2 / std::numbers::pi, 2);
  const double inf = std::numeric_limits<double>::infinity();
  for (int c = 0; c < p.image.channels; ++c) {
    ChannelDerived ch;
    ch.wavelength_m = channel_wavelength_m(p, c);
    const double k = wavenumber(ch.wavelength_m);
    ch.r0_m = r0_from(weighted_integral(in, p.path.wave), ch.wavelength_m);
    ch.d_over_r0 = o.aperture_m / ch.r0_m;
    // Isoplanatic angle (Fried 1982) with the scene at z = 0: the rays from two
    // scene points θ apart are θ (L − z) apart at z, so turbulence near the
    // scene weighs most.
    ch.isoplanatic_angle_rad =
        in.isoplanatic > 0
            ? std::pow(2.91 * k * k * std::pow(L, 5.0 / 3.0) * in.isoplanatic, -3.0 / 5.0)
            : inf;
    ch.isoplanatic_angle_px = ch.isoplanatic_angle_rad / d.ifov_rad;
    // Spherical-wave log-amplitude (Rytov) variance, Andrews & Phillips eq. 8.
    ch.rytov = 0.563 * std::pow(k, 7.0 / 6.0) * in.rytov;
    ch.nyquist = ch.wavelength_m * o.focal_length_m / (2 * o.aperture_m * d.pixel_pitch_m);
    const double lam_d = ch.wavelength_m / o.aperture_m;
    ch.tilt_std_rad = std::sqrt(tilt_var_unit * std::pow(ch.d_over_r0, 5.0 / 3.0)) * lam_d;
    ch.tilt_std_px = ch.tilt_std_rad / d.ifov_rad;
    ch.seeing_fwhm_px = 0.98 * ch.wavelength_m / ch.r0_m / d.ifov_rad;

    const std::string where =
        p.image.channels > 1 ? " (channel " + std::to_string(c) + ")" : std::string();
    if (ch.d_over_r0 > kDOverR0Max)
      throw InvalidArgument(kOp,
                            "D/r0 = " + num(ch.d_over_r0) + where + " exceeds " + num(kDOverR0Max) +
                                ": the " + std::to_string(p.zernike_modes) +
                                "-mode Zernike model cannot represent this phase",
                            "reduce the aperture, the range or Cn² (or raise r0)");
    if (ch.rytov > kRytovMax)
      throw InvalidArgument(kOp,
                            "Rytov number σ_χ² = " + num(ch.rytov) + where + " exceeds " +
                                num(kRytovMax) +
                                ": scintillation is saturated and a phase-only model is void",
                            "reduce the range or Cn²");
    if (ch.d_over_r0 > kDOverR0Warn)
      d.warnings.push_back(
          "D/r0 = " + num(ch.d_over_r0) + where + " > " + num(kDOverR0Warn) + ": " +
          std::to_string(p.zernike_modes) +
          " Zernike modes leave a large residual phase; the blur is underestimated");
    if (ch.rytov > kRytovWarn)
      d.warnings.push_back("Rytov number σ_χ² = " + num(ch.rytov) + where + " > " +
                           num(kRytovWarn) +
                           ": scintillation is not negligible and the phase-only model ignores it");
    if (ch.nyquist < kNyquistWarn)
      d.warnings.push_back("Nyquist ratio λf/(2Dp) = " + num(ch.nyquist) + where + " < " +
                           num(kNyquistWarn) +
                           ": the detector undersamples the optics; fine PSF detail aliases");
    if (!std::isfinite(ch.r0_m) && c == 0)
      d.warnings.emplace_back("Cn² is zero along the whole path: no turbulence is simulated");
    d.channels.push_back(ch);
  }
  return d;
}

Params preset(std::string_view name) {
  Params p;  // moderate: D = 0.2 m, f = 1.6 m, 525 nm, 3.45 µm pixels, L = 1 km
  p.path.strength = Strength::constant_cn2;
  if (name == "weak") {
    p.path.cn2 = 1.25e-15;  // D/r0 ≈ 1.49
  } else if (name == "moderate") {
    p.path.cn2 = 4e-15;  // D/r0 ≈ 2.99
  } else if (name == "strong") {
    p.path.cn2 = 1.25e-14;  // D/r0 ≈ 5.93
  } else {
    std::string names;
    for (const auto& n : preset_names()) names += (names.empty() ? "" : ", ") + n;
    throw InvalidArgument("sim::preset", "unknown preset '" + std::string(name) + "'",
                          "use one of " + names);
  }
  return p;
}

std::vector<std::string> preset_names() { return {"weak", "moderate", "strong"}; }

std::string summary(const Params& p, const Derived& d) {
  const ChannelDerived& c = d.channels.front();
  char buf[512];
  std::snprintf(buf, sizeof buf,
                "L=%.4g m D=%.4g m f=%.4g m λ=%.4g nm r0=%.3g cm D/r0=%.3g θ0=%.3g µrad (%.3g px) "
                "Rytov=%.3g Nyquist=%.3g tilt σ=%.3g px pixel@L=%.3g mm %d×%d×%d ×%d",
                p.path.range_m, p.optics.aperture_m, p.optics.focal_length_m, c.wavelength_m * 1e9,
                c.r0_m * 100, c.d_over_r0, c.isoplanatic_angle_rad * 1e6, c.isoplanatic_angle_px,
                c.rytov, c.nyquist, c.tilt_std_px, d.object_pixel_m * 1e3, p.image.height,
                p.image.width, p.image.channels, p.image.batch);
  std::string s = buf;
  if (d.channels.size() > 1) s += " (channel 0 of " + std::to_string(d.channels.size()) + ")";
  return s;
}

// ---- JSON ------------------------------------------------------------------

namespace {

struct Reader {
  std::string source;

  [[noreturn]] void fail(const std::string& key, const std::string& problem,
                         const std::string& fix) const {
    throw InvalidArgument("sim::params_from_json", source + ": " + key + " " + problem, fix);
  }

  void only_keys(const json& obj, const std::string& where,
                 std::initializer_list<const char*> allowed) const {
    for (const auto& item : obj.items()) {
      bool ok = false;
      std::string list;
      for (const char* a : allowed) {
        ok = ok || item.key() == a;
        list += (list.empty() ? "" : ", ") + std::string(a);
      }
      if (!ok)
        fail(where.empty() ? item.key() : where + "." + item.key(), "is not a known key",
             "use one of: " + list + " (check the spelling)");
    }
  }

  const json* object(const json& parent, const char* key, const std::string& where) const {
    if (!parent.contains(key)) return nullptr;
    const json& v = parent.at(key);
    if (!v.is_object())
      fail(where, "must be an object ({...} in JSON, a mapping in YAML)",
           "see docs/sim.md for the layout");
    return &v;
  }

  double number(const json& v, const std::string& key) const {
    if (!v.is_number())
      fail(key, "must be a number, got " + std::string(v.type_name()), "write e.g. 0.2");
    return v.get<double>();
  }

  int integer(const json& v, const std::string& key) const {
    if (!v.is_number_integer())
      fail(key, "must be an integer, got " + std::string(v.type_name()), "write e.g. 256");
    const auto x = v.get<long long>();
    if (x < std::numeric_limits<int>::min() || x > std::numeric_limits<int>::max())
      fail(key, "is out of range", "give a smaller value");
    return static_cast<int>(x);
  }

  std::vector<double> numbers(const json& v, const std::string& key) const {
    if (v.is_number()) return {v.get<double>()};
    if (!v.is_array()) fail(key, "must be a number or an array of numbers", "write e.g. [525e-9]");
    std::vector<double> out;
    for (std::size_t i = 0; i < v.size(); ++i)
      out.push_back(number(v[i], key + "[" + std::to_string(i) + "]"));
    return out;
  }
};

}  // namespace

Params params_from_json(std::string_view text, std::string_view source) {
  Reader r{std::string(source)};
  json doc;
  try {
    doc = json::parse(text.begin(), text.end());
  } catch (const json::parse_error& e) {
    throw InvalidArgument("sim::params_from_json",
                          std::string(source) + " is not valid JSON: " + e.what(),
                          "fix the syntax (a trailing comma, a missing quote, …)");
  }
  if (!doc.is_object())
    r.fail("the top level", "must be an object ({...} in JSON, a mapping in YAML)",
           "see docs/sim.md for the layout");
  r.only_keys(doc, "", {"preset", "optics", "path", "image", "zernike_modes"});

  Params p;
  if (doc.contains("preset")) {
    if (!doc["preset"].is_string()) r.fail("preset", "must be a string", "write e.g. \"moderate\"");
    try {
      p = preset(doc["preset"].get<std::string>());
    } catch (const InvalidArgument& e) {
      r.fail("preset", "is unknown: " + doc["preset"].get<std::string>(), e.fix());
    }
  }

  if (const json* o = r.object(doc, "optics", "optics")) {
    r.only_keys(
        *o, "optics",
        {"aperture_m", "focal_length_m", "wavelengths_m", "pixel_pitch_m", "field_width_m"});
    if (o->contains("aperture_m"))
      p.optics.aperture_m = r.number(o->at("aperture_m"), "optics.aperture_m");
    if (o->contains("focal_length_m"))
      p.optics.focal_length_m = r.number(o->at("focal_length_m"), "optics.focal_length_m");
    if (o->contains("wavelengths_m"))
      p.optics.wavelengths_m = r.numbers(o->at("wavelengths_m"), "optics.wavelengths_m");
    const bool pitch = o->contains("pixel_pitch_m");
    const bool field = o->contains("field_width_m");
    if (pitch && field)
      r.fail("optics.pixel_pitch_m and optics.field_width_m", "are both given",
             "give one of them: the other follows from the focal length and the range");
    if (pitch) {
      p.optics.sampling = Sampling::pixel_pitch;
      p.optics.pixel_pitch_m = r.number(o->at("pixel_pitch_m"), "optics.pixel_pitch_m");
    }
    if (field) {
      p.optics.sampling = Sampling::field_width;
      p.optics.field_width_m = r.number(o->at("field_width_m"), "optics.field_width_m");
    }
  }

  if (const json* pa = r.object(doc, "path", "path")) {
    r.only_keys(*pa, "path", {"range_m", "wave", "r0_m", "r0_wavelength_m", "cn2", "cn2_profile"});
    if (pa->contains("range_m")) p.path.range_m = r.number(pa->at("range_m"), "path.range_m");
    if (pa->contains("wave")) {
      const json& w = pa->at("wave");
      const std::string s = w.is_string() ? w.get<std::string>() : std::string();
      if (s == "spherical")
        p.path.wave = WaveModel::spherical;
      else if (s == "plane")
        p.path.wave = WaveModel::plane;
      else
        r.fail("path.wave", "must be \"spherical\" or \"plane\"",
               "use \"spherical\" for a scene at finite range (the usual case)");
    }
    const int given =
        int(pa->contains("r0_m")) + int(pa->contains("cn2")) + int(pa->contains("cn2_profile"));
    if (given > 1)
      r.fail("path.r0_m / path.cn2 / path.cn2_profile", "give the turbulence strength twice",
             "keep exactly one of them");
    if (pa->contains("r0_wavelength_m") && !pa->contains("r0_m"))
      r.fail("path.r0_wavelength_m", "is given without path.r0_m", "add r0_m or remove it");
    if (pa->contains("r0_m")) {
      p.path.strength = Strength::r0;
      p.path.r0_m = r.number(pa->at("r0_m"), "path.r0_m");
      p.path.r0_wavelength_m = pa->contains("r0_wavelength_m")
                                   ? r.number(pa->at("r0_wavelength_m"), "path.r0_wavelength_m")
                                   : 0.0;
    }
    if (pa->contains("cn2")) {
      p.path.strength = Strength::constant_cn2;
      p.path.cn2 = r.number(pa->at("cn2"), "path.cn2");
    }
    if (const json* prof = r.object(*pa, "cn2_profile", "path.cn2_profile")) {
      r.only_keys(*prof, "path.cn2_profile", {"z_m", "cn2"});
      if (!prof->contains("z_m") || !prof->contains("cn2"))
        r.fail("path.cn2_profile", "needs both \"z_m\" and \"cn2\" arrays",
               "give positions from the scene (0) to the aperture and a Cn² per position");
      p.path.strength = Strength::cn2_profile;
      p.path.cn2_z_m = r.numbers(prof->at("z_m"), "path.cn2_profile.z_m");
      p.path.cn2_profile = r.numbers(prof->at("cn2"), "path.cn2_profile.cn2");
    }
  }

  if (const json* im = r.object(doc, "image", "image")) {
    r.only_keys(*im, "image", {"height", "width", "channels", "batch"});
    if (im->contains("height")) p.image.height = r.integer(im->at("height"), "image.height");
    if (im->contains("width")) p.image.width = r.integer(im->at("width"), "image.width");
    if (im->contains("channels"))
      p.image.channels = r.integer(im->at("channels"), "image.channels");
    if (im->contains("batch")) p.image.batch = r.integer(im->at("batch"), "image.batch");
  }
  if (doc.contains("zernike_modes"))
    p.zernike_modes = r.integer(doc["zernike_modes"], "zernike_modes");
  // One wavelength per channel and no image.channels: the channels follow the wavelengths.
  const bool channels_given =
      doc.contains("image") && doc["image"].is_object() && doc["image"].contains("channels");
  if (!channels_given && p.optics.wavelengths_m.size() > 1)
    p.image.channels = static_cast<int>(p.optics.wavelengths_m.size());

  try {
    validate(p);
  } catch (const InvalidArgument& e) {
    throw InvalidArgument("sim::params_from_json", std::string(source) + ": " + e.problem(),
                          e.fix());
  }
  return p;
}

std::string params_to_json(const Params& p) {
  json optics = {{"aperture_m", p.optics.aperture_m},
                 {"focal_length_m", p.optics.focal_length_m},
                 {"wavelengths_m", p.optics.wavelengths_m}};
  if (p.optics.sampling == Sampling::pixel_pitch)
    optics["pixel_pitch_m"] = p.optics.pixel_pitch_m;
  else
    optics["field_width_m"] = p.optics.field_width_m;
  json path = {{"range_m", p.path.range_m},
               {"wave", p.path.wave == WaveModel::spherical ? "spherical" : "plane"}};
  switch (p.path.strength) {
    case Strength::r0:
      path["r0_m"] = p.path.r0_m;
      if (p.path.r0_wavelength_m != 0) path["r0_wavelength_m"] = p.path.r0_wavelength_m;
      break;
    case Strength::constant_cn2:
      path["cn2"] = p.path.cn2;
      break;
    case Strength::cn2_profile:
      path["cn2_profile"] = {{"z_m", p.path.cn2_z_m}, {"cn2", p.path.cn2_profile}};
      break;
  }
  const json doc = {{"optics", optics},
                    {"path", path},
                    {"image",
                     {{"height", p.image.height},
                      {"width", p.image.width},
                      {"channels", p.image.channels},
                      {"batch", p.image.batch}}},
                    {"zernike_modes", p.zernike_modes}};
  return doc.dump(2) + "\n";
}

namespace {

bool is_yaml(const std::filesystem::path& path) {
  std::string ext = path.extension().string();
  for (char& c : ext) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  return ext == ".yaml" || ext == ".yml";
}

}  // namespace

Params load_params(const std::filesystem::path& path) {
  const auto bytes = vkjr2::read_file_bytes(path, "sim::load_params");
  const std::string text(reinterpret_cast<const char*>(bytes.data()), bytes.size());
  return is_yaml(path) ? params_from_yaml(text, path.string())
                       : params_from_json(text, path.string());
}

void save_params(const Params& params, const std::filesystem::path& path) {
  validate(params);
  const std::string text = is_yaml(path) ? params_to_yaml(params) : params_to_json(params);
  vkjr2::write_file_atomic(path, std::as_bytes(std::span(text.data(), text.size())),
                           "sim::save_params");
}

}  // namespace vkjr2::sim
