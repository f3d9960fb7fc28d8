#include <vkjr2/kernels/fft.hpp>
#include <vkjr2/runtime/error.hpp>
#include <vkjr2/runtime/stream.hpp>
#include <vkjr2/sim/phase_screen.hpp>
#include <vkjr2/sim/wave_optics.hpp>

#include <algorithm>
#include <cmath>
#include <complex>
#include <cstdint>
#include <cstdio>
#include <numbers>
#include <string>

namespace vkjr2::sim {
namespace {

constexpr double kPi = std::numbers::pi;
constexpr int kMaxScreens = 1000;
constexpr const char* kOp = "sim::wave_optics";

struct ModulatePush {
  std::uint32_t n, m, batch, use_screen, screen_offset, mask_offset, shift_offset, term_offset,
      term_count;
};
static_assert(sizeof(ModulatePush) <= 128);

// ∫_a^b Cn²(z) w(z) dz by composite Simpson (the weights are smooth inside a
// slab; their end-point singularities at z = 0, L cost < 1e-4 relative).
template <class Weight>
double slab_integral(const Params& params, double a, double b, Weight weight) {
  constexpr int kIntervals = 256;
  const double h = (b - a) / kIntervals;
  double sum = 0;
  for (int i = 0; i <= kIntervals; ++i) {
    const double z = a + i * h;
    const double coefficient = (i == 0 || i == kIntervals) ? 1 : (i % 2 ? 4 : 2);
    sum += coefficient * cn2_at(params, z) * weight(z);
  }
  return sum * h / 3;
}

void validate(const WaveConfig& config) {
  if (config.grid < 8 || !kernels::fft_supported_length(config.grid)) {
    throw InvalidArgument(
        kOp, "WaveConfig::grid " + std::to_string(config.grid) + " is not an FFT length ≥ 8",
        "use a product of 2, 3, 5, 7 such as 128 or 256");
  }
  if (config.screen_size != 0 &&
      (config.screen_size < config.grid || !kernels::fft_supported_length(config.screen_size))) {
    throw InvalidArgument(kOp,
                          "WaveConfig::screen_size " + std::to_string(config.screen_size) +
                              " must be 0 or an FFT length ≥ grid",
                          "use 0 (screens as large as the grid) or e.g. 2 × grid");
  }
  if (config.screens < 1 || config.screens > kMaxScreens) {
    throw InvalidArgument(kOp, "WaveConfig::screens must be in 1.." + std::to_string(kMaxScreens),
                          "use 10 (the usual)");
  }
  if (!(config.grid_over_aperture > 1) || !std::isfinite(config.grid_over_aperture)) {
    throw InvalidArgument(kOp, "WaveConfig::grid_over_aperture must be finite and > 1",
                          "use 2.5: the grid must hold the aperture and a guard band");
  }
  if (!(config.max_rytov > 0)) {
    throw InvalidArgument(kOp, "WaveConfig::max_rytov must be > 0", "use 0.1");
  }
  if (!(config.inner_scale_m >= 0) || !std::isfinite(config.inner_scale_m) ||
      !(config.outer_scale_m > 0)) {
    throw InvalidArgument(kOp, "WaveConfig inner scale must be ≥ 0 and outer scale > 0",
                          "use 0 and infinity for pure Kolmogorov turbulence");
  }
  for (const double o : config.screen_offset_m) {
    if (!std::isfinite(o) || std::abs(o) > 100) {
      throw InvalidArgument(kOp, "WaveConfig::screen_offset_m must be finite and within ±100 m",
                            "give the screens' displacement in metres, e.g. 0.02 per frame");
    }
  }
}

// Each slab's spherical-weighted integral ∫ Cn² (z/L)^(5/3) dz and Rytov share.
struct Slabs {
  std::vector<double> z, spherical, rytov;
};
Slabs slabs(const Params& params, double k, int n) {
  const double length = params.path.range_m;
  Slabs s;
  for (int i = 0; i < n; ++i) {
    const double a = length * i / n;
    const double b = length * (i + 1) / n;
    s.z.push_back(0.5 * (a + b));
    s.spherical.push_back(
        slab_integral(params, a, b, [&](double z) { return std::pow(z / length, 5.0 / 3.0); }));
    // Andrews & Phillips 2005, ch. 8: σ_χ² = 0.563 k^(7/6) ∫ Cn² (1 − z/L)^(5/6) z^(5/6) dz.
    s.rytov.push_back(0.563 * std::pow(k, 7.0 / 6.0) * slab_integral(params, a, b, [&](double z) {
                        return std::pow(std::max(0.0, 1 - z / length), 5.0 / 6.0) *
                               std::pow(z, 5.0 / 6.0);
                      }));
  }
  return s;
}

int signed_bin(int u, int n) { return u <= n / 2 ? u : u - n; }

// The inputs of the split steps, laid out as shaders/wave_modulate.comp reads them.
struct HostModulation {
  int n, m;
  std::size_t batch, terms_per_screen;
  std::span<const float> screens, masks, shifts, terms;
};

// Deep subharmonic levels as a polynomial. A term Re(c (e^{iθ} − 1)),
// θ = α u + β v (u = x/N, v = y/N in pixels from the grid centre), is
// −Im(c) θ − Re(c) θ²/2 + Im(c) θ³/6 + Re(c) θ⁴/24 + O(|c| θ⁵/120); with
// θ ≤ kPolynomialMaxPhase over every sample read that is ≤ 1e-7 |c|, below the
// float rounding of the phase. Coefficients of u^i v^(d−i), by degree d = 1..4
// and i = d..0: 14 of them.
constexpr std::size_t kPolynomialCoefficients = 14;
constexpr std::size_t kPolynomialTexels = 4;
constexpr double kPolynomialMaxPhase = 0.1;

// Levels evaluated term by term: level p's points have |fx| + |fy| ≤
// 2/(3^p M) cycles per pixel, so θ ≤ 2π·2·reach/(3^p M) at |x|, |y| ≤ reach px.
int exact_subharmonic_levels(int levels, int m, double reach_px) {
  int p = 1;
  double scale = 3;
  while (p <= levels && 2 * kPi * 2 * reach_px / (scale * m) > kPolynomialMaxPhase) {
    ++p;
    scale *= 3;
  }
  return p - 1;
}

std::array<double, kPolynomialCoefficients> subharmonic_polynomial(
    std::span<const Subharmonic> terms, double dx, int n) {
  std::array<double, kPolynomialCoefficients> a{};
  for (const Subharmonic& t : terms) {
    const double alpha = 2 * kPi * t.fx_per_m * dx * n, beta = 2 * kPi * t.fy_per_m * dx * n;
    const double re = t.coefficient.real(), im = t.coefficient.imag();
    const std::array<double, 5> weight{0, -im, -re / 2, im / 6, re / 24};
    std::size_t k = 0;
    for (int d = 1; d <= 4; ++d) {
      double binomial = 1;  // C(d, i), i from d down to 0
      for (int i = d; i >= 0; --i) {
        a[k++] += weight[std::size_t(d)] * binomial * std::pow(alpha, i) * std::pow(beta, d - i);
        binomial = binomial * i / (d - i + 1);
      }
    }
  }
  return a;
}

double evaluate_polynomial(const float* a, double u, double v) {
  const std::array<double, 5> up{1, u, u * u, u * u * u, u * u * u * u};
  const std::array<double, 5> vp{1, v, v * v, v * v * v, v * v * v * v};
  double sum = 0;
  std::size_t k = 0;
  for (std::size_t d = 1; d <= 4; ++d)
    for (std::size_t i = d + 1; i-- > 0;) sum += double(a[k++]) * up[i] * vp[d - i];
  return sum;
}

// wave_modulate on the host, for one screen and every source: field *=
// mask 0 · exp(i φ(x + shift)), φ bilinear in the periodic screen (wrapped)
// plus the subharmonic terms at the shifted position. Within a source the
// shift is one vector, so the bilinear weights are constant and the terms
// separable: Re(c e^{2πi(fx x + fy y)}) = Re(c ex[col] ey[row]).
void modulate_on_host(const HostModulation& mod, std::size_t screen, std::span<float> field) {
  const int n = mod.n;
  const int m = mod.m;
  const std::size_t plane = std::size_t(n) * n;
  const std::size_t terms = mod.terms_per_screen - kPolynomialTexels;  // exact terms
  const float* poly = &mod.terms[(screen * mod.terms_per_screen + terms) * 4];
  const float* phase = &mod.screens[screen * std::size_t(m) * m];
  const float* absorber = mod.masks.data();  // mask 0
  std::vector<std::complex<double>> ex(terms * n), ey(terms * n);
  std::vector<int> col0(n), col1(n), row0(n), row1(n);
  std::vector<double> phi(n);
  const auto wrap = [m](int v) { return ((v % m) + m) % m; };
  const int centre = n / 2;          // x = 0 at grid sample N/2 ...
  const int origin = m / 2 - n / 2;  // ... and screen sample M/2
  for (std::size_t b = 0; b < mod.batch; ++b) {
    const float* shift = &mod.shifts[(screen * mod.batch + b) * 2];
    const double xs0 = double(shift[0]) + origin;  // screen column of grid column 0
    const double ys0 = double(shift[1]) + origin;
    const double x_floor = std::floor(xs0);
    const double y_floor = std::floor(ys0);
    const double tx = xs0 - x_floor;
    const double ty = ys0 - y_floor;
    for (int i = 0; i < n; ++i) {
      col0[i] = wrap(int(x_floor) + i);
      col1[i] = wrap(int(x_floor) + i + 1);
      row0[i] = wrap(int(y_floor) + i);
      row1[i] = wrap(int(y_floor) + i + 1);
    }
    for (std::size_t t = 0; t < terms; ++t) {
      const float* term = &mod.terms[(screen * mod.terms_per_screen + t) * 4];
      const std::complex<double> coefficient(term[2], term[3]);
      for (int i = 0; i < n; ++i) {
        const double x = double(i - centre) + shift[0];
        const double y = double(i - centre) + shift[1];
        ex[t * n + i] = std::polar(1.0, 2 * kPi * term[0] * x);
        ey[t * n + i] = coefficient * std::polar(1.0, 2 * kPi * term[1] * y);
      }
    }
    float* f = &field[b * plane * 2];
    for (int r = 0; r < n; ++r) {
      const float* s0 = phase + std::size_t(row0[r]) * m;
      const float* s1 = phase + std::size_t(row1[r]) * m;
      for (int c = 0; c < n; ++c) {
        const double top = s0[col0[c]] + tx * (s0[col1[c]] - s0[col0[c]]);
        const double bottom = s1[col0[c]] + tx * (s1[col1[c]] - s1[col0[c]]);
        phi[c] = top + ty * (bottom - top);
      }
      for (std::size_t t = 0; t < terms; ++t) {
        const std::complex<double> h = ey[t * n + r];
        const std::complex<double>* e = &ex[t * n];
        const double piston = mod.terms[(screen * mod.terms_per_screen + t) * 4 + 2];  // Re(c)
        for (int c = 0; c < n; ++c)
          phi[c] += h.real() * e[c].real() - h.imag() * e[c].imag() - piston;
      }
      const double row_v = (double(r - centre) + shift[1]) / n;
      for (int c = 0; c < n; ++c)
        phi[c] += evaluate_polynomial(poly, (double(c - centre) + shift[0]) / n, row_v);
      for (int c = 0; c < n; ++c) {
        const std::size_t p = std::size_t(r) * n + c;
        const std::complex<double> k =
            std::complex<double>(absorber[2 * p], absorber[2 * p + 1]) * std::polar(1.0, phi[c]);
        const std::complex<double> u(f[2 * p], f[2 * p + 1]);
        const std::complex<double> v = u * k;
        f[2 * p] = static_cast<float>(v.real());
        f[2 * p + 1] = static_cast<float>(v.imag());
      }
    }
  }
}

// field *= mask `mask` (a Fresnel transfer function), every source.
void multiply_on_host(const HostModulation& mod, std::size_t mask, std::span<float> field) {
  const std::size_t plane = std::size_t(mod.n) * mod.n;
  const float* h = &mod.masks[mask * plane * 2];
  for (std::size_t b = 0; b < mod.batch; ++b) {
    float* f = &field[b * plane * 2];
    for (std::size_t p = 0; p < plane; ++p) {
      const float re = f[2 * p] * h[2 * p] - f[2 * p + 1] * h[2 * p + 1];
      const float im = f[2 * p] * h[2 * p + 1] + f[2 * p + 1] * h[2 * p];
      f[2 * p] = re;
      f[2 * p + 1] = im;
    }
  }
}

// The split steps of propagate() on the CPU (FftBackend::fftw).
std::vector<float> propagate_on_host(const HostModulation& mod, std::size_t screens) {
  const std::size_t plane = std::size_t(mod.n) * mod.n;
  FftwFloats field(mod.batch * plane * 2, 0.0f);
  for (std::size_t i = 0; i < mod.batch * plane; ++i) field[2 * i] = 1.0f;  // plane wave
  const Shape shape{std::int64_t(mod.batch), mod.n, mod.n};
  for (std::size_t i = 0; i < screens; ++i) {
    modulate_on_host(mod, i, field);  // screen i and the absorber
    fft2_fftw(shape, field, /*inverse=*/false);
    multiply_on_host(mod, i + 1, field);  // propagate to the next plane
    fft2_fftw(shape, field, /*inverse=*/true);
  }
  return {field.begin(), field.end()};
}

std::vector<float> propagate(const Device& device, const Params& params, const WavePlan& plan,
                             const WaveConfig& config,
                             std::span<const std::array<double, 2>> angles_rad) {
  const int n = plan.grid;
  const int m = plan.screen_size;
  const double dx = plan.spacing_m;
  const double length = params.path.range_m;
  const std::size_t plane = std::size_t(n) * n;
  const std::size_t screen_plane = std::size_t(m) * m;
  const std::size_t screens = plan.z_m.size();
  const std::size_t batch = angles_rad.size();
  if (batch == 0) return {};
  for (const auto& angle : angles_rad) {
    if (!std::isfinite(angle[0]) || !std::isfinite(angle[1]) || std::abs(angle[0]) > 0.1 ||
        std::abs(angle[1]) > 0.1) {
      throw InvalidArgument(kOp, "field angles must be finite and within ±0.1 rad (paraxial)",
                            "give angles in radians, e.g. 20e-6");
    }
  }

  // Screens in the ξ frame; slabs without turbulence get none.
  std::vector<ScreenLayer> layers;
  std::vector<std::size_t> layer_of(screens, SIZE_MAX);
  for (std::size_t i = 0; i < screens; ++i) {
    if (!std::isfinite(plan.r0_scaled_m[i])) continue;
    const double scale = length / plan.z_m[i];
    layer_of[i] = layers.size();
    layers.push_back(
        {plan.r0_scaled_m[i], config.inner_scale_m * scale, config.outer_scale_m * scale});
  }
  const ScreenParts parts = phase_screen_parts(device, ScreenGrid{m, dx, config.subharmonic_levels},
                                               layers, config.seed, config.fft);
  // Per screen and source: the shear θ L (L − z)/z of the screen, plus the
  // frozen-flow offset scaled into the ξ frame (× L/z), in pixels.
  std::vector<float> shifts(screens * batch * 2);
  double max_shift_px = 0;
  for (std::size_t i = 0; i < screens; ++i) {
    const double z = plan.z_m[i];
    for (std::size_t b = 0; b < batch; ++b) {
      for (int axis = 0; axis < 2; ++axis) {
        const double px = (angles_rad[b][axis] * length * (length - z) / z +
                           config.screen_offset_m[std::size_t(axis)] * length / z) /
                          dx;
        shifts[(i * batch + b) * 2 + axis] = static_cast<float>(px);
        max_shift_px = std::max(max_shift_px, std::abs(px));
      }
    }
  }

  // Subharmonic levels 1..exact are evaluated term by term; the deeper ones,
  // smooth across everything the sources read, as one polynomial per screen.
  const int exact = exact_subharmonic_levels(config.subharmonic_levels, m, n / 2.0 + max_shift_px);
  const std::size_t exact_terms = 4 * std::size_t(exact);
  const std::size_t terms_per_screen = exact_terms + kPolynomialTexels;
  std::vector<float> screen_values(screens * screen_plane, 0.0f);
  // Texels: exact terms (fx, fy in cycles per pixel, coefficient re, im),
  // then the polynomial's 14 coefficients (and 2 zeros).
  std::vector<float> term_values(screens * terms_per_screen * 4, 0.0f);
  for (std::size_t i = 0; i < screens; ++i) {
    if (layer_of[i] == SIZE_MAX) continue;
    std::copy_n(&parts.periodic[layer_of[i] * screen_plane], screen_plane,
                &screen_values[i * screen_plane]);
    const auto& sh = parts.subharmonics[layer_of[i]];
    for (std::size_t t = 0; t < std::min(exact_terms, sh.size()); ++t) {
      float* v = &term_values[(i * terms_per_screen + t) * 4];
      v[0] = static_cast<float>(sh[t].fx_per_m * dx);
      v[1] = static_cast<float>(sh[t].fy_per_m * dx);
      v[2] = static_cast<float>(sh[t].coefficient.real());
      v[3] = static_cast<float>(sh[t].coefficient.imag());
    }
    const std::array<double, kPolynomialCoefficients> poly =
        subharmonic_polynomial(std::span(sh).subspan(std::min(exact_terms, sh.size())), dx, n);
    float* v = &term_values[(i * terms_per_screen + exact_terms) * 4];
    for (std::size_t k = 0; k < poly.size(); ++k) v[k] = static_cast<float>(poly[k]);
  }

  // Mask 0: the absorber (Schmidt 2010, §8.6: exp(−(r/w)^16), w = 0.47 N δ);
  // masks 1..n: the Fresnel transfer function exp(−iπ λ Δζ f²) of each step.
  std::vector<float> masks((screens + 1) * plane * 2);
  const double w = 0.47 * n * dx;
  const int centre = n / 2;  // x = 0 at sample N/2
  for (int r = 0; r < n; ++r) {
    for (int c = 0; c < n; ++c) {
      const double rho = std::hypot((c - centre) * dx, (r - centre) * dx) / w;
      const std::size_t p = std::size_t(r) * n + c;
      masks[2 * p] = config.absorber ? static_cast<float>(std::exp(-std::pow(rho, 16))) : 1.0f;
      masks[2 * p + 1] = 0;
    }
  }
  const double df = 1 / (n * dx);
  for (std::size_t i = 0; i < screens; ++i) {
    float* h = &masks[(i + 1) * plane * 2];
    for (int u = 0; u < n; ++u) {
      for (int v = 0; v < n; ++v) {
        const double fy = signed_bin(u, n) * df;
        const double fx = signed_bin(v, n) * df;
        const double phase = std::fmod(
            -kPi * plan.wavelength_m * plan.propagation_m[i] * (fx * fx + fy * fy), 2 * kPi);
        const std::size_t p = std::size_t(u) * n + v;
        h[2 * p] = static_cast<float>(std::cos(phase));
        h[2 * p + 1] = static_cast<float>(std::sin(phase));
      }
    }
  }

  if (config.fft == FftBackend::fftw) {
    const HostModulation mod{n,     m,      batch,      terms_per_screen, screen_values,
                             masks, shifts, term_values};
    return propagate_on_host(mod, screens);
  }

  std::vector<float> field_values(batch * plane * 2);
  for (std::size_t i = 0; i < batch * plane; ++i) field_values[2 * i] = 1.0f;  // plane wave

  const auto b64 = static_cast<std::int64_t>(batch);
  const Tensor screen_t =
      Tensor::from(device, Shape{std::int64_t(screens * screen_plane)}, screen_values);
  const Tensor mask_t = Tensor::from(device, Shape{std::int64_t((screens + 1) * plane), 2}, masks);
  const Tensor shift_t = Tensor::from(device, Shape{std::int64_t(screens * batch), 2}, shifts);
  const Tensor term_t =
      Tensor::from(device, Shape{std::int64_t(term_values.size() / 4), 4}, term_values);
  const Tensor field = Tensor::from(device, Shape{b64, n, n, 2}, field_values);
  const kernels::FftPlan fft(device, Shape{b64, n, n}, kernels::FftKind::c2c);

  static const KernelDef kModulate{"wave_modulate",
                                   {BindingKind::texel, BindingKind::texel, BindingKind::texel,
                                    BindingKind::texel, BindingKind::storage},
                                   sizeof(ModulatePush)};
  const Groups groups = groups_1d(div_up(batch * plane, 256), device.info());
  const auto modulate = [&](Stream& stream, bool use_screen, std::size_t screen, std::size_t mask) {
    const ModulatePush push{std::uint32_t(n),
                            std::uint32_t(m),
                            std::uint32_t(batch),
                            use_screen ? 1u : 0u,
                            std::uint32_t(screen * screen_plane),
                            std::uint32_t(mask * plane),
                            std::uint32_t(screen * batch),
                            std::uint32_t(screen * terms_per_screen),
                            use_screen ? std::uint32_t(exact_terms) : 0u};
    stream.dispatch(kModulate,
                    {texel(screen_t), texel(mask_t, VK_FORMAT_R32G32_SFLOAT),
                     texel(shift_t, VK_FORMAT_R32G32_SFLOAT),
                     texel(term_t, VK_FORMAT_R32G32B32A32_SFLOAT), inout(field)},
                    push, groups);
  };
  Stream stream(device);
  for (std::size_t i = 0; i < screens; ++i) {
    modulate(stream, true, i, 0);  // screen i and the absorber
    fft.forward(stream, field, field);
    modulate(stream, false, 0, i + 1);  // propagate to the next plane
    fft.inverse(stream, field, field);
  }
  stream.run();
  field.download(field_values);
  return field_values;
}

}  // namespace

WavePlan plan_wave(const Params& params, int channel, const WaveConfig& config) {
  validate(config);
  const Derived derived = derive(params);
  if (channel < 0 || channel >= int(derived.channels.size())) {
    throw InvalidArgument(kOp, "channel " + std::to_string(channel) + " out of range",
                          "use 0.." + std::to_string(derived.channels.size() - 1));
  }
  WavePlan plan;
  plan.wavelength_m = channel_wavelength_m(params, channel);
  plan.grid = config.grid;
  plan.screen_size = config.screen_size == 0 ? config.grid : config.screen_size;
  const double k = 2 * kPi / plan.wavelength_m;
  const double aperture = params.optics.aperture_m;
  const double length = params.path.range_m;
  // δ = λ f/(p Nf): the focal sample of an Nf-point transform is the pitch.
  const double lambda_f_over_p =
      plan.wavelength_m * params.optics.focal_length_m / derived.pixel_pitch_m;
  const double target_spacing = config.grid_over_aperture * aperture / config.grid;
  plan.pupil_fft = int(kernels::fft_next_length(
      std::max<std::int64_t>(2, std::int64_t(std::ceil(lambda_f_over_p / target_spacing)))));
  plan.spacing_m = lambda_f_over_p / plan.pupil_fft;

  int n = config.screens;
  Slabs s = slabs(params, k, n);
  for (;;) {
    const double worst = *std::max_element(s.rytov.begin(), s.rytov.end());
    if (worst <= config.max_rytov) break;
    if (n >= kMaxScreens) {
      plan.warnings.push_back("a slab's Rytov number " + std::to_string(worst) +
                              " exceeds max_rytov with " + std::to_string(n) + " screens");
      break;
    }
    n = std::min(kMaxScreens, std::max(n + 1, int(std::ceil(n * worst / config.max_rytov))));
    s = slabs(params, k, n);
  }
  double total = 0;
  for (int i = 0; i < n; ++i) {
    const double z = s.z[i];
    // Fried 1967: r0^(−5/3) = 0.423 k² ∫ Cn² (z/L)^(5/3) dz, one slab per screen.
    const double strength = 0.423 * k * k * s.spherical[i];
    total += strength;
    const double r0_scaled =
        strength > 0 ? std::pow(strength, -3.0 / 5.0) : std::numeric_limits<double>::infinity();
    plan.z_m.push_back(z);
    plan.r0_scaled_m.push_back(r0_scaled);
    plan.r0_m.push_back(r0_scaled * z / length);
    plan.rytov.push_back(s.rytov[i]);
    const double next = i + 1 < n ? s.z[i + 1] : length;
    plan.propagation_m.push_back(length * length * (1 / z - 1 / next));
  }
  plan.r0_spherical_m =
      total > 0 ? std::pow(total, -3.0 / 5.0) : std::numeric_limits<double>::infinity();
  if (plan.r0_spherical_m < 3 * plan.spacing_m) {
    plan.warnings.push_back("grid spacing " + std::to_string(plan.spacing_m) +
                            " m is coarse for r0 = " + std::to_string(plan.r0_spherical_m) +
                            " m; raise WaveConfig::grid or lower grid_over_aperture");
  }
  if (params.path.wave == WaveModel::plane) {
    plan.warnings.emplace_back(
        "the wave-optics reference propagates point sources (spherical waves); its r0 is the "
        "spherical-wave r0, not the plane-wave one Params asks for");
  }
  return plan;
}

std::vector<float> wave_aperture_fields(const Device& device, const Params& params, int channel,
                                        const WaveConfig& config,
                                        std::span<const std::array<double, 2>> angles_rad) {
  const WavePlan plan = plan_wave(params, channel, config);
  return propagate(device, params, plan, config, angles_rad);
}

std::vector<float> wave_psfs(const Device& device, const Params& params, int channel,
                             const WaveConfig& config,
                             std::span<const std::array<double, 2>> angles_rad, int psf_size) {
  const WavePlan plan = plan_wave(params, channel, config);
  const int nf = plan.pupil_fft;
  if (psf_size < 1 || psf_size > nf) {
    throw InvalidArgument(kOp,
                          "psf_size " + std::to_string(psf_size) + " is outside 1.." +
                              std::to_string(nf) + " (the PSF's period in pixels)",
                          "ask for a smaller PSF or raise WaveConfig::grid");
  }
  const std::vector<float> fields = propagate(device, params, plan, config, angles_rad);
  const std::size_t batch = angles_rad.size();
  if (batch == 0) return {};
  const int n = plan.grid;
  const std::size_t plane = std::size_t(n) * n;
  const std::size_t fplane = std::size_t(nf) * nf;
  const double radius = params.optics.aperture_m / 2;

  // Pupil field folded modulo Nf: the Nf-point DFT of the folded field gives
  // exact samples of the pupil's Fourier transform at u = λ f k/(Nf δ) = k p,
  // whether the pupil is narrower (zero padding) or wider (folding) than Nf δ.
  std::vector<float> pupil(batch * fplane * 2, 0.0f);
  const auto wrap = [nf](int v) { return ((v % nf) + nf) % nf; };
  const int centre = n / 2;
  for (std::size_t b = 0; b < batch; ++b) {
    for (int r = 0; r < n; ++r) {
      for (int c = 0; c < n; ++c) {
        const double x = (c - centre) * plan.spacing_m;
        const double y = (r - centre) * plan.spacing_m;
        if (x * x + y * y > radius * radius) continue;
        const std::size_t src = b * plane + std::size_t(r) * n + c;
        const std::size_t dst = b * fplane + std::size_t(wrap(r - centre)) * nf + wrap(c - centre);
        pupil[2 * dst] += fields[2 * src];
        pupil[2 * dst + 1] += fields[2 * src + 1];
      }
    }
  }
  const auto b64 = static_cast<std::int64_t>(batch);
  fft2_host(config.fft, device, Shape{b64, nf, nf}, pupil, /*inverse=*/false,
            kernels::FftNorm::none);

  const std::size_t out_plane = std::size_t(psf_size) * psf_size;
  std::vector<float> psfs(batch * out_plane);
  for (std::size_t b = 0; b < batch; ++b) {
    double sum = 0;
    std::vector<double> psf(out_plane);
    for (int r = 0; r < psf_size; ++r) {
      for (int c = 0; c < psf_size; ++c) {
        const std::size_t src =
            b * fplane + std::size_t(wrap(r - psf_size / 2)) * nf + wrap(c - psf_size / 2);
        const double re = pupil[2 * src];
        const double im = pupil[2 * src + 1];
        psf[std::size_t(r) * psf_size + c] = re * re + im * im;
        sum += re * re + im * im;
      }
    }
    for (std::size_t i = 0; i < out_plane; ++i) {
      psfs[b * out_plane + i] = static_cast<float>(psf[i] / sum);
    }
  }
  return psfs;
}

}  // namespace vkjr2::sim
