#include <vkjr2/runtime/error.hpp>
#include <vkjr2/sim/field.hpp>
#include <vkjr2/sim/noll.hpp>
#include <vkjr2/sim/phase_screen.hpp>
#include <vkjr2/sim/short_exposure.hpp>
#include <vkjr2/sim/tilt.hpp>
#include <vkjr2/sim/validate.hpp>
#include <vkjr2/sim/wave_optics.hpp>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <numbers>

namespace vkjr2::sim {

bool ValidationRow::pass() const { return std::fabs(measured - expected) <= tolerance; }

MeanEstimate mean_and_error(const std::vector<double>& samples) {
  double s = 0, s2 = 0;
  for (double x : samples) {
    s += x;
    s2 += x * x;
  }
  const double n = double(samples.size()), m = s / n;
  return {m, std::sqrt(std::max(0.0, s2 / n - m * m) / std::max(1.0, n - 1))};
}

namespace {

ValidationRow row_4sigma(std::string check, const std::vector<double>& samples, double expected,
                         std::string note = {}) {
  const MeanEstimate m = mean_and_error(samples);
  return {std::move(check), m.mean, m.sigma, expected, 4 * m.sigma, std::move(note)};
}

constexpr int kBatch = 10;
constexpr double kPi = std::numbers::pi;

// Noll covariance, tilt in pixels, tilt correlation at a few lags, AR(1).
// Returns the measured one-axis tilt variance (px²).
MeanEstimate field_checks(const Device& device, const Params& base, const ValidationConfig& c,
                          std::vector<ValidationRow>& rows) {
  Params p = base;
  p.image = {96, 128, 1, kBatch};
  const Derived d = derive(p);
  FieldOptions o;
  o.tilt_rho = 0.9;
  o.high_order_rho = 0.5;
  TurbulenceField f(device, p, o);
  const int gh = f.grid_h(), gw = f.grid_w(), points = gh * gw, k = f.modes();
  const double scale = std::pow(d.channels[0].d_over_r0, 5.0 / 3.0);
  std::vector<double> a22, a44, a28, tilt2, corr_x, corr_y, ar_tilt, ar_high;
  const int lag = std::max(1, gw / 3);
  Stream s(device);
  for (int seq = 0; seq < std::max(1, c.fields / kBatch); ++seq) {
    f.reset(c.seed + std::uint64_t(seq));
    f.next(s);
    s.run();
    const auto all0 = f.coefficients().download();
    const auto tilt = f.tilt_px().download();
    f.next(s);
    s.run();
    const auto all1 = f.coefficients().download();
    for (int b = 0; b < kBatch; ++b) {
      const float* a = &all0[std::size_t(b) * points * k];
      const float* a1 = &all1[std::size_t(b) * points * k];
      const float* t = &tilt[std::size_t(b) * 2 * points];
      double s22 = 0, s44 = 0, s28 = 0, st = 0, cx = 0, cy = 0, ct = 0, vt = 0, ch = 0, vh = 0;
      int nx = 0, ny = 0;
      for (int y = 0; y < gh; ++y) {
        for (int x = 0; x < gw; ++x) {
          const int q = y * gw + x;
          s22 += double(a[q]) * a[q];
          s44 += double(a[2 * points + q]) * a[2 * points + q];
          s28 += double(a[q]) * a[6 * points + q];
          st += double(t[q]) * t[q];
          ct += double(a[q]) * a1[q];
          vt += double(a[q]) * a[q];
          ch += double(a[2 * points + q]) * a1[2 * points + q];
          vh += double(a[2 * points + q]) * a[2 * points + q];
          if (x + lag < gw) {
            cx += double(a[q]) * a[q + lag];
            ++nx;
          }
          if (y + lag < gh) {
            cy += double(a[q]) * a[q + lag * gw];
            ++ny;
          }
        }
      }
      const double var2 = noll_covariance(2, 2) * scale;
      a22.push_back(s22 / points);
      a44.push_back(s44 / points);
      a28.push_back(s28 / points);
      tilt2.push_back(st / points);
      corr_x.push_back(cx / nx / var2);
      corr_y.push_back(cy / ny / var2);
      ar_tilt.push_back(ct / vt);
      ar_high.push_back(ch / vh);
    }
  }
  rows.push_back(
      row_4sigma("<a2^2> (rad^2)", a22, noll_covariance(2, 2) * scale, "Noll x (D/r0)^(5/3)"));
  rows.push_back(
      row_4sigma("<a4^2> (rad^2)", a44, noll_covariance(4, 4) * scale, "Noll x (D/r0)^(5/3)"));
  rows.push_back(
      row_4sigma("<a2 a8> (rad^2)", a28, noll_covariance(2, 8) * scale, "Noll x (D/r0)^(5/3)"));
  const double tilt_std = d.channels[0].tilt_std_px;
  rows.push_back(row_4sigma("one-axis tilt variance (px^2)", tilt2, tilt_std * tilt_std,
                            "0.182 (lambda/D)^2 (D/r0)^(5/3) in px"));
  const double dx = lag * f.step_x_px() * d.ifov_rad, dy = lag * f.step_y_px() * d.ifov_rad;
  rows.push_back(row_4sigma("Z2 correlation, " + std::to_string(lag) + " grid steps along x",
                            corr_x, f.correlation()(2, dx, 0),
                            "path-integrated theory (longitudinal)"));
  rows.push_back(row_4sigma("Z2 correlation, " + std::to_string(lag) + " grid steps along y",
                            corr_y, f.correlation()(2, 0, dy),
                            "path-integrated theory (transverse)"));
  rows.push_back(row_4sigma("AR(1) lag-1, tilt", ar_tilt, o.tilt_rho, "seed rho"));
  rows.push_back(row_4sigma("AR(1) lag-1, high order (a4)", ar_high, o.high_order_rho, "seed rho"));
  return mean_and_error(tilt2);
}

// Structure function of the FFT phase screens (with subharmonics) at N/8
// and N/4, against the screens' exact expectation; Kolmogorov in the note.
void screen_checks(const Device& device, const ValidationConfig& c,
                   std::vector<ValidationRow>& rows) {
  const ScreenGrid grid{128, 0.005, 10};
  const ScreenLayer layer{0.05};
  const auto screens = phase_screens(device, grid, layer, c.screens, c.seed);
  const int n = grid.size;
  for (int lag : {n / 8, n / 4}) {
    std::vector<double> per_screen;
    for (int i = 0; i < c.screens; ++i) {
      const float* s = &screens[std::size_t(i) * n * n];
      double acc = 0;
      for (int y = 0; y < n; ++y)
        for (int x = 0; x + lag < n; ++x)
          acc += std::pow(double(s[y * n + x + lag]) - s[y * n + x], 2);
      per_screen.push_back(acc / (double(n) * (n - lag)));
    }
    const double r = lag * grid.spacing_m;
    const double kolmogorov = structure_function_constant() * std::pow(r / layer.r0_m, 5.0 / 3.0);
    rows.push_back(row_4sigma("phase-screen D(r = " + std::to_string(lag) + " dx) (rad^2)",
                              per_screen, screen_structure_function(grid, layer, r),
                              "Kolmogorov 6.88 (r/r0)^(5/3) = " + std::to_string(kolmogorov)));
  }
}

// 50 % encircled-energy radius (px) of a centred S×S PSF.
double ee50_radius(const std::vector<double>& psf, int s) {
  std::vector<std::pair<double, double>> rv;
  const double c = (s - 1) / 2.0;
  double total = 0;
  for (int y = 0; y < s; ++y)
    for (int x = 0; x < s; ++x) {
      rv.emplace_back(std::hypot(x - c, y - c), psf[std::size_t(y) * s + x]);
      total += psf[std::size_t(y) * s + x];
    }
  std::sort(rv.begin(), rv.end());
  // Linear in the cumulative energy between consecutive pixel radii.
  double acc = 0, r_prev = 0;
  for (const auto& [r, v] : rv) {
    if (acc + v >= 0.5 * total) return r_prev + (r - r_prev) * (0.5 * total - acc) / v;
    acc += v;
    r_prev = r;
  }
  return rv.back().first;
}

// Real part of the OTF of a PSF (h × w, row-major, pixel (r, c) at offset
// (c − cx, r − cy) from the optical axis) at ν cycles/px along x or y,
// shifted by −(sx, sy) px (removing a tilt of (sx, sy)), over the PSF's sum.
double otf_re(const float* psf, int h, int w, double cx, double cy, double nu, bool along_y,
              double sx = 0, double sy = 0) {
  double re = 0, total = 0;
  for (int r = 0; r < h; ++r)
    for (int c = 0; c < w; ++c) {
      const double v = psf[std::size_t(r) * w + c];
      const double t = along_y ? r - cy - sy : c - cx - sx;
      re += v * std::cos(2 * kPi * nu * t);
      total += v;
    }
  return re / total;
}

// Centroid (x, y), relative to (cx, cy), of one period (h × w) of a periodic
// PSF, as the circular mean along each axis: the phase of the PSF's first
// Fourier coefficient, n/(2π) · arg Σ v e^{2πi t/n}. A pure shift moves it by
// exactly the shift; the linear first moment over the period would not — the
// far wings that wrap around the period pull it toward the window's centre
// (by about the share of energy at the period's edge: 5 % of the tilt
// variance at the presets' 63-px period, measured).
std::array<double, 2> centroid(const float* psf, int h, int w, double cx, double cy) {
  double cxr = 0, cxi = 0, cyr = 0, cyi = 0;
  for (int r = 0; r < h; ++r)
    for (int c = 0; c < w; ++c) {
      const double v = psf[std::size_t(r) * w + c];
      const double ax = 2 * kPi * (c - cx) / w, ay = 2 * kPi * (r - cy) / h;
      cxr += v * std::cos(ax);
      cxi += v * std::sin(ax);
      cyr += v * std::cos(ay);
      cyi += v * std::sin(ay);
    }
  return {std::atan2(cxi, cxr) * w / (2 * kPi), std::atan2(cyi, cyr) * h / (2 * kPi)};
}

// Bilinear (align-corners) sample of plane `plane` of a [planes, gh, gw] grid
// stretched over an h × w image, at pixel (y, x).
double grid_at(const float* grid, int plane, int gh, int gw, int h, int w, double y, double x) {
  const double gy = h > 1 ? y * (gh - 1) / (h - 1) : 0, gx = w > 1 ? x * (gw - 1) / (w - 1) : 0;
  const int y0 = std::min(int(gy), gh - 1), x0 = std::min(int(gx), gw - 1);
  const int y1 = std::min(y0 + 1, gh - 1), x1 = std::min(x0 + 1, gw - 1);
  const double fy = gy - y0, fx = gx - x0;
  const float* g = grid + std::size_t(plane) * gh * gw;
  const auto at = [&](int yy, int xx) { return double(g[std::size_t(yy) * gw + xx]); };
  return (1 - fy) * ((1 - fx) * at(y0, x0) + fx * at(y0, x1)) +
         fy * ((1 - fx) * at(y1, x0) + fx * at(y1, x1));
}

// Diffraction OTF of a circular pupil at separation u = r/D (continuous).
double pupil_otf(double u) {
  if (u >= 1) return 0;
  return 2 / kPi * (std::acos(u) - u * std::sqrt(1 - u * u));
}

// The wave reference's own vacuum OTF at a shift of k samples: the overlap of
// its sampled pupil (the samples of the N grid within D/2, wave_psfs) with
// itself shifted by k along x, over its area.
double sampled_pupil_otf(int n, double spacing_m, double radius_m, int k) {
  const int centre = n / 2;
  const auto inside = [&](int r, int c) {
    const double x = (c - centre) * spacing_m, y = (r - centre) * spacing_m;
    return x * x + y * y <= radius_m * radius_m;
  };
  double both = 0, area = 0;
  for (int r = 0; r < n; ++r)
    for (int c = 0; c < n; ++c) {
      if (!inside(r, c)) continue;
      area += 1;
      if (c + k < n && inside(r, c + k)) both += 1;
    }
  return both / area;
}

// Point-source statistics of both simulators on the same parameters:
// - the long-exposure PSF's 50 % encircled-energy radius, fast (as rendered:
//   warp + blur) vs wave optics. They are different models (P2S's PSF error
//   is ≈ 0.2, docs/p2s.md; the screens lack some low-order power), so the
//   tolerance is stated: 15 % of the reference;
// - the atmospheric OTF (the OTF over the diffraction OTF) at pupil
//   separations r = 0.1 D and 0.2 D, long exposure (tilt kept) and short
//   exposure (tilt removed), against exp{−3.44 (r/r0)^(5/3) [1 − α (r/D)^(1/3)]}
//   with α = 0 and α = 1 (Fried 1966; near field: D ≫ √(λL)). The presets
//   sample at λf/(2Dp) ≈ 0.61, so the pixel-sampled OTF is alias-free only
//   below 1 − 1/(2q) cycles/px (r < (2q − 1) D ≈ 0.22 D): hence the two
//   low separations. Wave optics removes the G-tilt (the PSF centroid), the
//   fast simulator its Z-tilt (a_2, a_3: blur without warp); its long
//   exposure is the blur OTF times the tilt's phase e^(−2πiν·τ) at the
//   point (the warp's bilinear interpolation, which blurs a point source
//   but not a band-limited image, is left out);
// - the wave reference's one-axis G-tilt variance (PSF centroids) against
//   c_G (λ/D)² (D/r0)^(5/3) (g_tilt_constant) and against the fast
//   simulator's Z-tilt variance × c_G/c_Z.
//
// wavelength_m > 0 runs them at that wavelength (the same optics, another
// sampling and r0): the blur model whose sampling matches is taken from
// `blur`, and the rows' names end in "at N nm". Separations stay below the
// alias-free limit (2q − 1) D of that sampling.
// Pupil samples per diameter of the short-exposure theory (~1e-4 from converged).
constexpr int kTheoryGrid = 64;

void psf_checks(const Device& device, const Params& base, const ValidationConfig& c,
                const std::vector<std::shared_ptr<const BlurModel>>& blur,
                const MeanEstimate& fast_tilt_px2, std::vector<ValidationRow>& rows,
                double wavelength_m) {
  constexpr int kSize = 33, kFrame = 65;
  Params p = base;
  p.image = {kFrame, kFrame, 1, 1};
  std::string at;
  if (wavelength_m > 0) {
    set_wavelengths(p, {wavelength_m});
    char nm[32];
    std::snprintf(nm, sizeof nm, " at %.0f nm", wavelength_m * 1e9);
    at = nm;
  }
  const Derived d = derive(p);
  const double r0 = d.channels[0].r0_m, aperture = p.optics.aperture_m;
  WaveConfig w;
  w.grid = 128;
  w.screen_size = c.wave_screen_size;
  const WavePlan plan = plan_wave(p, 0, w);
  const int nf = plan.pupil_fft;
  // Separations on the wave grid (r = k δ, ν = k / Nf cycles/px for both):
  // 0.1 D and 0.2 D where they are alias-free, else one at 0.9 of the limit.
  const double alias_free = 2 * d.channels[0].nyquist - 1;
  std::vector<int> shifts;
  for (double u : {0.1, 0.2}) {
    const int k = std::max(1, int(std::lround(u * aperture / plan.spacing_m)));
    if (k * plan.spacing_m < alias_free * aperture) shifts.push_back(k);
  }
  if (shifts.empty())
    shifts.push_back(std::max(1, int(0.9 * alias_free * aperture / plan.spacing_m)));
  std::vector<double> fast(kSize * kSize, 0.0), wave(kSize * kSize, 0.0);
  Simulator sim(device, p, blur, {});
  SimOptions blur_only;
  blur_only.tilt = false;
  Simulator sim_blur(device, p, blur, blur_only);
  std::vector<float> point(kFrame * kFrame, 0.f);
  point[std::size_t(kFrame / 2) * kFrame + kFrame / 2] = 1.f;
  Tensor x = Tensor::from(device, {1, 1, kFrame, kFrame}, point);
  Tensor y = Tensor::empty(device, x.shape());
  Stream s(device);
  // [long/short][separation] per frame, and the wave tilts per axis.
  std::array<std::vector<std::vector<double>>, 2> otf_fast, otf_wave;
  for (auto* o : {&otf_fast, &otf_wave})
    for (auto& e : *o) e.resize(shifts.size());
  std::vector<double> wave_tilt2;
  constexpr int kCentre = kFrame / 2;
  const double cf = kCentre;
  for (int t = 0; t < c.psf_frames; ++t) {
    // The fast simulator as rendered (EE50).
    sim.reset(c.seed + 100 + std::uint64_t(t));
    sim.frame(s, x, y);
    s.run();
    const auto v = y.download();
    for (int yy = 0; yy < kSize; ++yy)
      for (int xx = 0; xx < kSize; ++xx)
        fast[std::size_t(yy) * kSize + xx] +=
            v[std::size_t(yy + (kFrame - kSize) / 2) * kFrame + xx + (kFrame - kSize) / 2];
    // Its blur alone, and the tilt at the point.
    sim_blur.reset(c.seed + 500 + std::uint64_t(t));
    sim_blur.frame(s, x, y);
    s.run();
    const auto b = y.download();
    const auto tilt = sim_blur.field().tilt_px().download();
    const int gh = sim_blur.field().grid_h(), gw = sim_blur.field().grid_w();
    const double tx = grid_at(tilt.data(), 0, gh, gw, kFrame, kFrame, cf, cf);
    const double ty = grid_at(tilt.data(), 1, gh, gw, kFrame, kFrame, cf, cf);
    // The wave reference: one full period of its PSF, centred at Nf/2.
    w.seed = c.seed + 1000 + std::uint64_t(t);
    const std::array<double, 2> on_axis{0.0, 0.0};
    const auto psf = wave_psfs(device, p, 0, w, std::span(&on_axis, 1), nf);
    const int half = nf / 2;
    const double cw = half;
    for (int yy = 0; yy < kSize; ++yy)
      for (int xx = 0; xx < kSize; ++xx)
        wave[std::size_t(yy) * kSize + xx] +=
            psf[std::size_t(yy + nf / 2 - kSize / 2) * nf + xx + nf / 2 - kSize / 2];
    const auto g = centroid(psf.data(), nf, nf, cw, cw);
    wave_tilt2.push_back((g[0] * g[0] + g[1] * g[1]) / 2);
    for (std::size_t i = 0; i < shifts.size(); ++i) {
      const double nu = double(shifts[i]) / nf;
      const auto both_axes = [&](auto f) { return (f(false) + f(true)) / 2; };
      otf_wave[0][i].push_back(
          both_axes([&](bool ay) { return otf_re(psf.data(), nf, nf, cw, cw, nu, ay); }));
      otf_wave[1][i].push_back(both_axes(
          [&](bool ay) { return otf_re(psf.data(), nf, nf, cw, cw, nu, ay, g[0], g[1]); }));
      otf_fast[0][i].push_back(both_axes(
          [&](bool ay) { return otf_re(b.data(), kFrame, kFrame, cf, cf, nu, ay, -tx, -ty); }));
      otf_fast[1][i].push_back(
          both_axes([&](bool ay) { return otf_re(b.data(), kFrame, kFrame, cf, cf, nu, ay); }));
    }
  }
  const double r_fast = ee50_radius(fast, kSize), r_wave = ee50_radius(wave, kSize);
  rows.push_back({"long-exposure PSF, 50% energy radius (px)" + at, r_fast, 0, r_wave,
                  0.15 * r_wave,
                  "fast simulator vs wave optics, " + std::to_string(c.psf_frames) +
                      " frames each; tolerance 15 %"});
  const double d_over_r0 = aperture / r0;
  for (int exposure = 0; exposure < 2; ++exposure) {
    const char* name = exposure == 0 ? "long" : "short";
    for (std::size_t i = 0; i < shifts.size(); ++i) {
      const double r = shifts[i] * plan.spacing_m, u = r / aperture;
      // Long exposure: exp(-3.44 (r/r0)^(5/3)). Short exposure: the exact
      // mean OTF for Gaussian phase with each model's own tilt removed
      // (sim/short_exposure.hpp); Fried's alpha = 1 form is within 0.002 of
      // it at r = 0.1 D and 0.008 below it at 0.2 D.
      const double fried = std::exp(-3.44 * std::pow(r / r0, 5.0 / 3.0) *
                                    (1 - (exposure == 0 ? 0.0 : std::cbrt(u))));
      const double theory_wave = atmospheric_otf(
          u, d_over_r0, exposure == 0 ? TiltRemoval::none : TiltRemoval::centroid, kTheoryGrid);
      const double theory_fast = atmospheric_otf(
          u, d_over_r0, exposure == 0 ? TiltRemoval::none : TiltRemoval::zernike, kTheoryGrid);
      char sep[32], fried_note[64];
      std::snprintf(sep, sizeof sep, "r = %.3f D%s", u, at.c_str());
      std::snprintf(fried_note, sizeof fried_note, " (Fried alpha = 1: %.4f)", fried);
      // Over each model's own diffraction OTF.
      const double vac_wave = sampled_pupil_otf(plan.grid, plan.spacing_m, aperture / 2, shifts[i]);
      std::vector<double> ratio_wave, ratio_fast;
      for (double o : otf_wave[exposure][i]) ratio_wave.push_back(o / vac_wave);
      for (double o : otf_fast[exposure][i]) ratio_fast.push_back(o / pupil_otf(u));
      rows.push_back(row_4sigma(
          std::string("wave optics: ") + name + "-exposure MTF, " + sep, ratio_wave, theory_wave,
          exposure == 0 ? std::string("exp(-3.44 (r/r0)^(5/3))")
                        : "exact, G-tilt (centroid) removed" + std::string(fried_note)));
      // The fast simulator against theory: statistical 4σ plus its stated
      // model error (P2S PSF, modes ≤ j_max, the S×S basis crop): 0.05.
      ValidationRow f = row_4sigma(
          std::string("fast sim: ") + name + "-exposure MTF, " + sep, ratio_fast, theory_fast,
          exposure == 0
              ? std::string("exp(-3.44 (r/r0)^(5/3)); tolerance 4 sigma + 0.05")
              : "exact, Z-tilt removed" + std::string(fried_note) + "; tolerance 4 sigma + 0.05");
      f.tolerance += 0.05;
      rows.push_back(std::move(f));
    }
  }
  const double px2 = 1 / (d.ifov_rad * d.ifov_rad);
  rows.push_back(row_4sigma("wave optics: one-axis G-tilt variance (px^2)" + at, wave_tilt2,
                            g_tilt_angle_variance_rad2(p) * px2,
                            "PSF centroids vs c_G (lambda/D)^2 (D/r0)^(5/3), c_G = 0.1698"));
  const MeanEstimate wt = mean_and_error(wave_tilt2);
  const double g_over_z = g_tilt_angle_variance_rad2(p) / tilt_angle_variance_rad2(p);
  const double sigma = std::hypot(wt.sigma, g_over_z * fast_tilt_px2.sigma);
  rows.push_back({"fast sim vs wave optics: one-axis tilt variance (px^2)" + at,
                  fast_tilt_px2.mean * g_over_z, sigma, wt.mean, 4 * sigma,
                  "fast Z-tilt variance x c_G/c_Z = 0.933 vs wave centroids; 4 sigma of both"});
}

}  // namespace

std::vector<ValidationRow> validate_simulator(const Device& device, const std::string& preset_name,
                                              const ValidationConfig& config,
                                              const std::shared_ptr<const BlurModel>& blur,
                                              const std::function<void(int, int)>& progress) {
  std::vector<std::shared_ptr<const BlurModel>> models;
  if (blur) models.push_back(blur);
  return validate_simulator(device, preset_name, config, models, progress);
}

std::vector<ValidationRow> validate_simulator(
    const Device& device, const std::string& preset_name, const ValidationConfig& config,
    const std::vector<std::shared_ptr<const BlurModel>>& blur,
    const std::function<void(int, int)>& progress) {
  if (config.fields < kBatch || config.screens < 2 || config.psf_frames < 2) {
    throw InvalidArgument("validate_simulator",
                          "needs fields >= 10, screens >= 2 and psf_frames >= 2");
  }
  for (const double wl : config.extra_wavelengths_m) {
    if (!(wl > 0) || !std::isfinite(wl) || blur.empty()) {
      throw InvalidArgument("validate_simulator",
                            "extra_wavelengths_m needs positive wavelengths in metres and blur "
                            "models for them");
    }
  }
  const Params base = preset(preset_name);
  std::vector<ValidationRow> rows;
  const int total = blur.empty() ? 2 : 3 + int(config.extra_wavelengths_m.size());
  const MeanEstimate tilt = field_checks(device, base, config, rows);
  if (progress) progress(1, total);
  screen_checks(device, config, rows);
  if (progress) progress(2, total);
  if (!blur.empty()) {
    psf_checks(device, base, config, blur, tilt, rows, 0);
    if (progress) progress(3, total);
    int done = 3;
    // The tilt in pixels is achromatic (angle ∝ λ/D · (D/r0)^(5/6) ∝ λ^0),
    // so the field's tilt statistics serve every wavelength.
    for (const double wl : config.extra_wavelengths_m) {
      psf_checks(device, base, config, blur, tilt, rows, wl);
      if (progress) progress(++done, total);
    }
  }
  return rows;
}

}  // namespace vkjr2::sim
