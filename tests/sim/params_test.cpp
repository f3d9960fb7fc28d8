#include <vkjr2/runtime/error.hpp>
#include <vkjr2/sim/params.hpp>

#include <gtest/gtest.h>
#include <unistd.h>

#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <functional>
#include <iterator>
#include <limits>
#include <numbers>
#include <string>

namespace vkjr2::sim {
namespace {

constexpr double kPi = std::numbers::pi;

double k_of(double lambda) { return 2 * kPi / lambda; }
double beta(double a, double b) { return std::tgamma(a) * std::tgamma(b) / std::tgamma(a + b); }

// The message of the InvalidArgument fn throws ("(no error)" when none).
std::string error_of(const std::function<void()>& fn) {
  try {
    fn();
  } catch (const InvalidArgument& e) {
    return e.what();
  }
  return "(no error)";
}

TEST(SimParams, PresetsGiveTheDocumentedStrengths) {
  // D/r0 ≈ 1.5 / 3 / 6 at L = 1 km, λ = 525 nm, D = 0.2 m, from the
  // spherical-wave closed form (0.158625 k² Cn² L)^(−3/5) computed here.
  const std::array<double, 3> want{1.49, 2.99, 5.93};
  const auto names = preset_names();
  ASSERT_EQ(names.size(), 3u);
  for (std::size_t i = 0; i < names.size(); ++i) {
    const Params p = preset(names[i]);
    const Derived d = derive(p);
    const double k = k_of(p.optics.wavelengths_m[0]);
    const double r0 = std::pow(0.158625 * k * k * p.path.cn2 * p.path.range_m, -3.0 / 5.0);
    EXPECT_NEAR(d.channels[0].r0_m / r0, 1.0, 1e-8) << names[i];
    EXPECT_NEAR(d.channels[0].d_over_r0, want[i], 0.01) << names[i];
    EXPECT_TRUE(d.warnings.empty()) << names[i] << ": " << d.warnings.front();
    const std::string s = summary(p, d);
    EXPECT_NE(s.find("D/r0="), std::string::npos) << s;
    EXPECT_EQ(s.find('\n'), std::string::npos) << s;
    std::printf("%s: %s\n", names[i].c_str(), s.c_str());
  }
  EXPECT_EQ(derive(Params{}).channels[0].d_over_r0,
            derive(preset("moderate")).channels[0].d_over_r0);
  EXPECT_NE(error_of([] { preset("medium"); }).find("moderate"), std::string::npos);
}

TEST(SimParams, ConstantCn2ClosedForms) {
  Params p = preset("moderate");
  const double k = k_of(525e-9);
  const double cn2 = p.path.cn2;
  const double L = p.path.range_m;
  const Derived d = derive(p);
  const ChannelDerived& c = d.channels[0];
  // θ0 = (2.91 k² L^(5/3) Cn² ∫(1 − z/L)^(5/3) dz)^(−3/5), ∫ = 3L/8.
  EXPECT_NEAR(c.isoplanatic_angle_rad /
                  std::pow(2.91 * 3.0 / 8.0 * k * k * cn2 * std::pow(L, 8.0 / 3.0), -3.0 / 5.0),
              1.0, 1e-8);
  // σ_χ² = 0.563 k^(7/6) Cn² L^(11/6) B(11/6, 11/6) = 0.124 k^(7/6) Cn² L^(11/6).
  EXPECT_NEAR(c.rytov / (0.563 * std::pow(k, 7.0 / 6.0) * cn2 * std::pow(L, 11.0 / 6.0) *
                         beta(11.0 / 6.0, 11.0 / 6.0)),
              1.0, 1e-7);
  EXPECT_NEAR(c.rytov / (0.124 * std::pow(k, 7.0 / 6.0) * cn2 * std::pow(L, 11.0 / 6.0)), 1.0,
              2e-3);
  EXPECT_NEAR(c.nyquist, 525e-9 * 1.6 / (2 * 0.2 * 3.45e-6), 1e-12);
  EXPECT_NEAR(d.ifov_rad, 3.45e-6 / 1.6, 1e-18);
  EXPECT_NEAR(d.object_pixel_m, 1000 * 3.45e-6 / 1.6, 1e-15);
  EXPECT_NEAR(c.isoplanatic_angle_px, c.isoplanatic_angle_rad / d.ifov_rad, 1e-9);
  EXPECT_NEAR(d.cn2_path_integral, cn2 * L, 1e-9 * cn2 * L);
  // Plane wave: (0.423 k² Cn² L)^(−3/5), smaller than the spherical r0.
  p.path.wave = WaveModel::plane;
  const double r0_plane = derive(p).channels[0].r0_m;
  EXPECT_NEAR(r0_plane / std::pow(0.423 * k * k * cn2 * L, -3.0 / 5.0), 1.0, 1e-8);
  EXPECT_LT(r0_plane, c.r0_m);
}

TEST(SimParams, ProfileIntegrals) {
  // A linear profile Cn²(z) = c z/L against the Beta-function integrals.
  Params p = preset("moderate");
  const double L = 2000;
  const double cmax = 1e-14;
  p.path.range_m = L;
  p.path.strength = Strength::cn2_profile;
  p.path.cn2_z_m = {0, L};
  p.path.cn2_profile = {0, cmax};
  const PathIntegrals in = path_integrals(p);
  EXPECT_NEAR(in.plain / (cmax * L / 2), 1.0, 1e-10);
  EXPECT_NEAR(in.spherical / (cmax * L * 3 / 11), 1.0, 1e-10);
  EXPECT_NEAR(in.isoplanatic / (cmax * L * beta(2, 8.0 / 3.0)), 1.0, 1e-9);
  EXPECT_NEAR(in.rytov / (cmax * std::pow(L, 11.0 / 6.0) * beta(17.0 / 6.0, 11.0 / 6.0)), 1.0,
              1e-7);
  // Values are held beyond the first and last sample: a two-point constant
  // profile in the middle of the path equals the constant everywhere.
  Params flat = preset("moderate");
  Params mid = flat;
  mid.path.strength = Strength::cn2_profile;
  mid.path.cn2_z_m = {400, 600};
  mid.path.cn2_profile = {flat.path.cn2, flat.path.cn2};
  const PathIntegrals a = path_integrals(flat);
  const PathIntegrals b = path_integrals(mid);
  EXPECT_NEAR(a.spherical / b.spherical, 1.0, 1e-12);
  EXPECT_NEAR(a.rytov / b.rytov, 1.0, 1e-12);
  // Turbulence near the aperture (z → L) lowers r0 more than the same
  // turbulence near the scene; turbulence near the scene lowers θ0 more (the
  // rays from two scene points separate as θ (L − z)).
  Params near_aperture = flat;
  near_aperture.path.strength = Strength::cn2_profile;
  near_aperture.path.cn2_z_m = {0, 900, 1000};
  near_aperture.path.cn2_profile = {0, 0, 2e-14};
  Params near_scene = near_aperture;
  near_scene.path.cn2_z_m = {0, 100, 1000};
  near_scene.path.cn2_profile = {2e-14, 0, 0};
  const Derived da = derive(near_aperture);
  const Derived ds = derive(near_scene);
  EXPECT_NEAR(da.cn2_path_integral, ds.cn2_path_integral, 1e-9 * da.cn2_path_integral);
  EXPECT_LT(da.channels[0].r0_m, ds.channels[0].r0_m);
  EXPECT_GT(da.channels[0].isoplanatic_angle_rad, ds.channels[0].isoplanatic_angle_rad);
}

TEST(SimParams, R0GivenDirectlyAndColour) {
  Params p = preset("moderate");
  p.path.strength = Strength::r0;
  p.path.r0_m = 0.05;
  p.path.r0_wavelength_m = 500e-9;
  p.image.channels = 3;
  p.optics.wavelengths_m = {620e-9, 525e-9, 460e-9};
  const Derived d = derive(p);
  ASSERT_EQ(d.channels.size(), 3u);
  for (const ChannelDerived& c : d.channels) {
    // r0 ∝ λ^(6/5); the tilt angle is achromatic.
    EXPECT_NEAR(c.r0_m / (0.05 * std::pow(c.wavelength_m / 500e-9, 1.2)), 1.0, 1e-8);
    EXPECT_NEAR(c.tilt_std_rad / d.channels[0].tilt_std_rad, 1.0, 1e-9);
  }
  EXPECT_NEAR(d.channels[0].d_over_r0 / d.channels[2].d_over_r0, std::pow(460.0 / 620.0, 1.2),
              1e-9);
  // With r0 at wavelengths_m[0] (r0_wavelength_m = 0), r0 is given exactly there.
  p.path.r0_wavelength_m = 0;
  EXPECT_NEAR(derive(p).channels[0].r0_m, 0.05, 1e-10);
  // The summary names the channel count.
  EXPECT_NE(summary(p, d).find("of 3"), std::string::npos);
  // set_wavelengths keeps that r0 at the wavelength it was given at.
  Params q = p;
  set_wavelengths(q, {700e-9});
  q.image.channels = 1;
  EXPECT_DOUBLE_EQ(q.path.r0_wavelength_m, 620e-9);
  EXPECT_NEAR(derive(q).channels[0].r0_m, 0.05 * std::pow(700.0 / 620.0, 1.2), 1e-10);
  // An r0 given at an explicit wavelength, or a Cn², is left as it is.
  q = p;
  q.path.r0_wavelength_m = 500e-9;
  set_wavelengths(q, {700e-9});
  EXPECT_DOUBLE_EQ(q.path.r0_wavelength_m, 500e-9);
  q = preset("moderate");
  set_wavelengths(q, {700e-9});
  EXPECT_EQ(q.path.r0_wavelength_m, 0.0);
  EXPECT_EQ(q.optics.wavelengths_m, std::vector<double>{700e-9});
}

TEST(SimParams, FieldWidthSamplingAndNonSquareImages) {
  Params p = preset("weak");
  p.image.height = 240;
  p.image.width = 320;
  p.optics.sampling = Sampling::field_width;
  p.optics.field_width_m = 0.8;
  const Derived d = derive(p);
  EXPECT_NEAR(d.pixel_pitch_m, 0.8 * 1.6 / (1000 * 320), 1e-18);
  EXPECT_NEAR(d.field_width_m, 0.8, 1e-12);
  EXPECT_NEAR(pixel_pitch_m(p), d.pixel_pitch_m, 0);
  EXPECT_NE(summary(p, d).find("240×320"), std::string::npos);
}

TEST(SimParams, InvalidValuesNameTheField) {
  const double nan = std::numeric_limits<double>::quiet_NaN();
  struct Case {
    const char* field;
    std::function<void(Params&)> edit;
  };
  const std::vector<Case> cases{
      {"optics.aperture_m", [](Params& p) { p.optics.aperture_m = 0; }},
      {"optics.aperture_m", [](Params& p) { p.optics.aperture_m = -0.1; }},
      {"optics.focal_length_m", [nan](Params& p) { p.optics.focal_length_m = nan; }},
      {"optics.wavelengths_m[0]", [](Params& p) { p.optics.wavelengths_m = {0}; }},
      {"optics.wavelengths_m[1]",
       [nan](Params& p) {
         p.image.channels = 2;
         p.optics.wavelengths_m = {500e-9, nan};
       }},
      {"optics.wavelengths_m[0]", [](Params& p) { p.optics.wavelengths_m = {525}; }},  // nm, not m
      {"optics.wavelengths_m", [](Params& p) { p.optics.wavelengths_m = {}; }},
      {"optics.wavelengths_m",
       [](Params& p) {
         p.image.channels = 3;
         p.optics.wavelengths_m = {500e-9, 600e-9};
       }},
      {"optics.pixel_pitch_m", [](Params& p) { p.optics.pixel_pitch_m = 0; }},
      {"optics.field_width_m", [](Params& p) { p.optics.sampling = Sampling::field_width; }},
      {"path.range_m", [](Params& p) { p.path.range_m = 0; }},
      {"path.range_m", [nan](Params& p) { p.path.range_m = nan; }},
      {"path.cn2", [](Params& p) { p.path.cn2 = -1e-15; }},
      {"path.cn2", [nan](Params& p) { p.path.cn2 = nan; }},
      {"path.r0_m", [](Params& p) { p.path.strength = Strength::r0; }},
      {"path.cn2_profile",
       [](Params& p) {
         p.path.strength = Strength::cn2_profile;
         p.path.cn2_z_m = {0, 10};
         p.path.cn2_profile = {1e-15};
       }},
      {"path.cn2_profile[1]",
       [](Params& p) {
         p.path.strength = Strength::cn2_profile;
         p.path.cn2_z_m = {0, 10};
         p.path.cn2_profile = {1e-15, -1e-15};
       }},
      {"path.cn2_z_m[1]",
       [](Params& p) {
         p.path.strength = Strength::cn2_profile;
         p.path.cn2_z_m = {10, 10};
         p.path.cn2_profile = {1e-15, 1e-15};
       }},
      {"path.cn2_z_m[0]",
       [](Params& p) {
         p.path.strength = Strength::cn2_profile;
         p.path.cn2_z_m = {-5};
         p.path.cn2_profile = {1e-15};
       }},
      {"image.width", [](Params& p) { p.image.width = 0; }},
      {"image.batch", [](Params& p) { p.image.batch = -2; }},
      {"zernike_modes", [](Params& p) { p.zernike_modes = 2; }},
  };
  for (const Case& c : cases) {
    Params p = preset("moderate");
    c.edit(p);
    const std::string msg = error_of([&] { derive(p); });
    EXPECT_NE(msg.find(c.field), std::string::npos) << "want " << c.field << ", got: " << msg;
    EXPECT_NE(msg.find("Fix:"), std::string::npos) << msg;
  }
}

TEST(SimParams, OutOfModelWarningsAndAbsurdErrors) {
  // Long strong path: scintillation (Rytov) and D/r0 warnings.
  Params p = preset("strong");
  p.path.range_m = 2000;
  p.path.cn2 = 6e-14;  // D/r0 ≈ 23, σ_χ² ≈ 1.5
  Derived d = derive(p);
  ASSERT_GT(d.channels[0].rytov, kRytovWarn);
  ASSERT_GT(d.channels[0].d_over_r0, kDOverR0Warn);
  auto has = [&d](const char* word) {
    for (const auto& w : d.warnings)
      if (w.find(word) != std::string::npos) return true;
    return false;
  };
  EXPECT_TRUE(has("Rytov"));
  EXPECT_TRUE(has("D/r0"));
  EXPECT_FALSE(has("Nyquist"));
  // Undersampled detector.
  Params coarse = preset("moderate");
  coarse.optics.pixel_pitch_m = 10e-6;
  d = derive(coarse);
  EXPECT_TRUE(has("Nyquist"));
  // Absurd: D/r0 way beyond the model, and saturated scintillation.
  Params absurd = preset("strong");
  absurd.optics.aperture_m = 5;
  EXPECT_NE(error_of([&] { derive(absurd); }).find("D/r0"), std::string::npos);
  absurd = preset("strong");
  absurd.path.range_m = 10000;
  absurd.path.cn2 = 7e-15;  // σ_χ² ≈ 3.4 while D/r0 ≈ 17 is still fine
  EXPECT_NE(error_of([&] { derive(absurd); }).find("Rytov"), std::string::npos);
  // No turbulence is allowed, with a warning.
  Params calm = preset("weak");
  calm.path.cn2 = 0;
  d = derive(calm);
  EXPECT_TRUE(std::isinf(d.channels[0].r0_m));
  EXPECT_EQ(d.channels[0].d_over_r0, 0.0);
  EXPECT_TRUE(has("no turbulence"));
}

TEST(SimParams, JsonRoundTrip) {
  Params p = preset("strong");
  p.optics.wavelengths_m = {620e-9, 525e-9, 460e-9};
  p.image = {480, 640, 3, 4};
  p.path.wave = WaveModel::plane;
  p.path.strength = Strength::cn2_profile;
  p.path.cn2_z_m = {0, 250.5, 1000};
  p.path.cn2_profile = {1e-15, 3.25e-14, 2e-15};
  p.zernike_modes = 45;
  const Params q = params_from_json(params_to_json(p));
  EXPECT_EQ(q.optics.aperture_m, p.optics.aperture_m);
  EXPECT_EQ(q.optics.focal_length_m, p.optics.focal_length_m);
  EXPECT_EQ(q.optics.wavelengths_m, p.optics.wavelengths_m);
  EXPECT_EQ(q.optics.pixel_pitch_m, p.optics.pixel_pitch_m);
  EXPECT_EQ(q.path.range_m, p.path.range_m);
  EXPECT_EQ(q.path.wave, WaveModel::plane);
  EXPECT_EQ(q.path.strength, Strength::cn2_profile);
  EXPECT_EQ(q.path.cn2_z_m, p.path.cn2_z_m);
  EXPECT_EQ(q.path.cn2_profile, p.path.cn2_profile);
  EXPECT_EQ(q.image.height, 480);
  EXPECT_EQ(q.image.width, 640);
  EXPECT_EQ(q.image.channels, 3);
  EXPECT_EQ(q.image.batch, 4);
  EXPECT_EQ(q.zernike_modes, 45);
  EXPECT_EQ(params_to_json(q), params_to_json(p));

  // r0 and field width round-trip too.
  Params r = preset("weak");
  r.path.strength = Strength::r0;
  r.path.r0_m = 0.07;
  r.path.r0_wavelength_m = 550e-9;
  r.optics.sampling = Sampling::field_width;
  r.optics.field_width_m = 1.5;
  const Params s = params_from_json(params_to_json(r));
  EXPECT_EQ(s.path.strength, Strength::r0);
  EXPECT_EQ(s.path.r0_m, 0.07);
  EXPECT_EQ(s.path.r0_wavelength_m, 550e-9);
  EXPECT_EQ(s.optics.sampling, Sampling::field_width);
  EXPECT_EQ(s.optics.field_width_m, 1.5);
}

TEST(SimParams, JsonPresetAndOverrides) {
  const Params p = params_from_json(
      R"({"preset": "weak", "path": {"r0_m": 0.1}, "image": {"width": 320}, "optics": {"wavelengths_m": 6e-7}})");
  EXPECT_EQ(p.path.strength, Strength::r0);
  EXPECT_EQ(p.path.r0_m, 0.1);
  EXPECT_EQ(p.image.width, 320);
  EXPECT_EQ(p.image.height, 256);
  EXPECT_EQ(p.optics.wavelengths_m, std::vector<double>{6e-7});
  EXPECT_EQ(p.optics.aperture_m, 0.2);
}

TEST(SimParams, JsonErrorsNameTheKey) {
  auto err = [](const std::string& text) {
    return error_of([&] { params_from_json(text, "cfg.json"); });
  };
  struct Case {
    const char* text;
    const char* want;
  };
  for (const Case& c : std::vector<Case>{
           {R"({"optics": {"aperture": 0.2}})", "optics.aperture"},
           {R"({"optic": {}})", "optic"},
           {R"({"path": {"range_m": "far"}})", "path.range_m must be a number"},
           {R"({"path": {"r0_m": 0.05, "cn2": 1e-15}})", "twice"},
           {R"({"optics": {"pixel_pitch_m": 3e-6, "field_width_m": 1}})", "both"},
           {R"({"image": {"height": 2.5}})", "image.height must be an integer"},
           {R"({"path": {"wave": "round"}})", "path.wave"},
           {R"({"path": {"cn2_profile": {"z_m": [0, 1]}}})", "path.cn2_profile"},
           {R"({"path": {"cn2_profile": {"z_m": [0, 1], "cn2": [1e-15, "x"]}}})",
            "path.cn2_profile.cn2[1]"},
           {R"({"path": {"range_m": -4}})", "path.range_m"},
           {R"({"preset": "medium"})", "preset"},
           {R"({"optics": {"wavelengths_m": []}})", "optics.wavelengths_m"},
           {R"({"path": {"range_m": 1000,}})", "not valid JSON"},
           {R"([1, 2])", "top level"},
           {R"({"path": {"r0_wavelength_m": 5e-7}})", "r0_wavelength_m"},
       }) {
    const std::string msg = err(c.text);
    EXPECT_NE(msg.find(c.want), std::string::npos) << c.text << " → " << msg;
    EXPECT_NE(msg.find("cfg.json"), std::string::npos) << msg;
  }
}

// The same configuration as YAML (comments, block and flow style, quoted
// and plain strings) and as JSON.
constexpr const char* kTwinYaml = R"(# a 3-channel profile case
preset: strong
optics:
  aperture_m: 0.25
  focal_length_m: 2.0
  wavelengths_m: [620e-9, 525e-9, 4.6e-7]
  field_width_m: 1.5
path:
  range_m: 1500
  wave: "plane"
  cn2_profile:
    z_m:
      - 0
      - 250.5
      - 1500
    cn2: [1e-15, 3.25e-14, 2e-15]
image: {height: 480, width: 640, channels: 3, batch: 2}
zernike_modes: 45
)";
constexpr const char* kTwinJson = R"({"preset": "strong",
 "optics": {"aperture_m": 0.25, "focal_length_m": 2.0,
            "wavelengths_m": [620e-9, 525e-9, 4.6e-7], "field_width_m": 1.5},
 "path": {"range_m": 1500, "wave": "plane",
          "cn2_profile": {"z_m": [0, 250.5, 1500], "cn2": [1e-15, 3.25e-14, 2e-15]}},
 "image": {"height": 480, "width": 640, "channels": 3, "batch": 2},
 "zernike_modes": 45})";

TEST(SimParams, YamlEqualsItsJsonTwin) {
  const Params y = params_from_yaml(kTwinYaml, "twin.yaml");
  const Params j = params_from_json(kTwinJson, "twin.json");
  EXPECT_EQ(params_to_json(y), params_to_json(j));
  EXPECT_EQ(y.path.cn2_z_m, (std::vector<double>{0, 250.5, 1500}));
  EXPECT_EQ(y.optics.wavelengths_m, (std::vector<double>{620e-9, 525e-9, 4.6e-7}));
  EXPECT_EQ(y.image.batch, 2);
  // params_to_yaml reads back to the same parameters, bit for bit.
  EXPECT_EQ(params_to_json(params_from_yaml(params_to_yaml(y))), params_to_json(y));
  // r0 with its wavelength, in flow style.
  const Params r = params_from_yaml("path: {r0_m: 0.07, r0_wavelength_m: 550e-9}\n");
  EXPECT_EQ(r.path.strength, Strength::r0);
  EXPECT_EQ(r.path.r0_m, 0.07);
  EXPECT_EQ(r.path.r0_wavelength_m, 550e-9);
}

TEST(SimParams, YamlErrorsNameTheKey) {
  struct Case {
    const char* text;
    const char* want;
  };
  for (const Case& c : std::vector<Case>{
           {"optics:\n  aperture: 0.2\n", "optics.aperture"},
           {"optic: {}\n", "optic"},
           {"path:\n  range_m: far\n", "path.range_m must be a number"},
           {"path:\n  range_m: \"1000\"\n", "path.range_m must be a number"},
           {"path: {r0_m: 0.05, cn2: 1e-15}\n", "twice"},
           {"optics: {pixel_pitch_m: 3e-6, field_width_m: 1}\n", "both"},
           {"image:\n  height: 2.5\n", "image.height must be an integer"},
           {"path:\n  cn2_profile: {z_m: [0, 1], cn2: [1e-15, x]}\n", "path.cn2_profile.cn2[1]"},
           {"path:\n  range_m: -4\n", "path.range_m"},
           {"preset: medium\n", "preset"},
           {"path:\n  range_m: 1000\n  range_m: 900\n", "path.range_m is given twice"},
           {"- 1\n- 2\n", "top level"},
           {"optics: 0.2\n", "optics must be an object"},
           {"path:\n  range_m: [1000\n", "not valid YAML: line"},
           {"optics:\n  aperture_m: 0.2\n   focal_length_m: 1\n", "not valid YAML"},
       }) {
    const std::string msg = error_of([&] { params_from_yaml(c.text, "cfg.yaml"); });
    EXPECT_NE(msg.find(c.want), std::string::npos) << c.text << " → " << msg;
    EXPECT_NE(msg.find("cfg.yaml"), std::string::npos) << msg;
  }
}

TEST(SimParams, LoadAndSavePickTheFormatByExtension) {
  const auto dir = std::filesystem::temp_directory_path() /
                   ("vkjr2_sim_params_yaml_" + std::to_string(::getpid()));
  std::filesystem::create_directories(dir);
  for (const char* name : {"twin.yaml", "twin.YML"}) {
    std::ofstream(dir / name) << kTwinYaml;
  }
  std::ofstream(dir / "twin.json") << kTwinJson;
  const std::string want = params_to_json(load_params(dir / "twin.json"));
  EXPECT_EQ(params_to_json(load_params(dir / "twin.yaml")), want);
  EXPECT_EQ(params_to_json(load_params(dir / "twin.YML")), want);
  // YAML is not read as JSON by a .json name (the JSON error names the file).
  std::ofstream(dir / "wrong.json") << kTwinYaml;
  const std::string msg = error_of([&] { load_params(dir / "wrong.json"); });
  EXPECT_NE(msg.find("not valid JSON"), std::string::npos) << msg;
  EXPECT_NE(msg.find("wrong.json"), std::string::npos) << msg;
  // A malformed YAML file: an error naming it and the line.
  std::ofstream(dir / "bad.yml") << "optics:\n  aperture_m: [0.2\n";
  const std::string bad = error_of([&] { load_params(dir / "bad.yml"); });
  EXPECT_NE(bad.find("bad.yml"), std::string::npos) << bad;
  EXPECT_NE(bad.find("line"), std::string::npos) << bad;
  // save_params writes YAML for a YAML name, and it loads back.
  const Params p = load_params(dir / "twin.json");
  save_params(p, dir / "saved.yaml");
  std::ifstream in(dir / "saved.yaml");
  const std::string text((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  EXPECT_EQ(text.find('{'), std::string::npos) << text;  // block style, not JSON
  EXPECT_EQ(params_to_json(load_params(dir / "saved.yaml")), want);
  std::filesystem::remove_all(dir);
}

TEST(SimParams, SaveAndLoadFiles) {
  const auto dir =
      std::filesystem::temp_directory_path() / ("vkjr2_sim_params_" + std::to_string(::getpid()));
  std::filesystem::create_directories(dir);
  const auto file = dir / "p.json";
  const Params p = preset("strong");
  save_params(p, file);
  EXPECT_EQ(params_to_json(load_params(file)), params_to_json(p));
  // No temporary files are left behind.
  int entries = 0;
  for (const auto& e : std::filesystem::directory_iterator(dir)) entries += e.is_regular_file();
  EXPECT_EQ(entries, 1);
  // Truncated file: a clear error naming it.
  {
    std::ofstream out(dir / "bad.json");
    out << R"({"optics": {"aperture_m": 0.)";
  }
  const std::string msg = error_of([&] { load_params(dir / "bad.json"); });
  EXPECT_NE(msg.find("bad.json"), std::string::npos) << msg;
  EXPECT_THROW(load_params(dir / "missing.json"), Error);
  Params invalid = p;
  invalid.optics.aperture_m = -1;
  EXPECT_THROW(save_params(invalid, dir / "x.json"), InvalidArgument);
  EXPECT_FALSE(std::filesystem::exists(dir / "x.json"));
  std::filesystem::remove_all(dir);
}

}  // namespace
}  // namespace vkjr2::sim
