#include <vkjr2/kernels/fft.hpp>
#include <vkjr2/runtime/error.hpp>
#include <vkjr2/runtime/stream.hpp>
#include <vkjr2/sim/noll.hpp>
#include <vkjr2/sim/phase_screen.hpp>
#include <vkjr2/sim/quadrature.hpp>

#include <algorithm>
#include <array>
#include <cmath>
#include <complex>
#include <numbers>
#include <string>
#include <utility>

namespace vkjr2::sim {
namespace {

constexpr double kPi = std::numbers::pi;
constexpr int kMaxSubharmonicLevels = 20;

void validate(const ScreenGrid& grid, std::span<const ScreenLayer> layers) {
  const char* op = "sim::phase_screens";
  if (grid.size < 2 || !kernels::fft_supported_length(grid.size)) {
    throw InvalidArgument(op, "grid.size " + std::to_string(grid.size) + " is not an FFT length",
                          "use a length ≥ 2 made of the factors 2, 3, 5, 7 (e.g. 256)");
  }
  if (!(grid.spacing_m > 0) || !std::isfinite(grid.spacing_m)) {
    throw InvalidArgument(op, "grid.spacing_m must be finite and > 0",
                          "give the sample spacing in metres");
  }
  if (grid.subharmonic_levels < 0 || grid.subharmonic_levels > kMaxSubharmonicLevels) {
    throw InvalidArgument(
        op, "grid.subharmonic_levels must be in 0.." + std::to_string(kMaxSubharmonicLevels),
        "use 3 (the usual) or 0 for none");
  }
  for (const ScreenLayer& layer : layers) {
    if (!(layer.r0_m > 0) || !std::isfinite(layer.r0_m)) {
      throw InvalidArgument(op, "layer r0_m must be finite and > 0", "give r0 in metres");
    }
    if (!(layer.inner_scale_m >= 0) || !std::isfinite(layer.inner_scale_m)) {
      throw InvalidArgument(op, "layer inner_scale_m must be finite and ≥ 0",
                            "use 0 for no inner scale");
    }
    if (!(layer.outer_scale_m > 0)) {
      throw InvalidArgument(op, "layer outer_scale_m must be > 0",
                            "use infinity for no outer scale");
    }
  }
}

// Signed frequency index of FFT bin u of an n-point transform.
int signed_bin(int u, int n) { return u <= n / 2 ? u : u - n; }

// Lattice bins with |u|, |v| ≤ this (and every subharmonic point) carry their
// cell's power, not the PSD at the point times the cell's area.
constexpr int kCellWeightedBins = 2;

// The variance given to the frequency point f_c of a square cell of side h:
// ∫_cell Φ(f) |f|² d²f / |f_c|². Near the origin Φ ∝ f^(−11/3) changes by
// 10× across a cell, so the point value Φ(f_c) h² leaves D(r) 23 % low at
// r = M dx/8 even with 3 subharmonic levels; weighting by |f|² keeps each
// cell's contribution to D(r) ≈ Σ 4π² (f·r)² var (the low cells' regime,
// r ≪ 1/f) exact (docs/sim.md, "Phase screens").
double cell_power(double fx, double fy, double h, const ScreenLayer& layer) {
  static const GaussLegendre gl(16);
  double s = 0;
  for (std::size_t i = 0; i < gl.x.size(); ++i) {
    const double x = fx + gl.x[i] * h / 2;
    for (std::size_t j = 0; j < gl.x.size(); ++j) {
      const double y = fy + gl.x[j] * h / 2;
      const double f2 = x * x + y * y;
      s += gl.w[i] * gl.w[j] * von_karman_psd(std::sqrt(f2), layer) * f2;
    }
  }
  return s * (h / 2) * (h / 2) / (fx * fx + fy * fy);
}

// Hermitian Gaussian spectrum with ⟨|c(f)|²⟩ = Φ(f) Δf² (screen_lattice_variance: the
// cell-weighted power near the origin), so that its inverse
// DFT (unnormalized) is a real screen with the PSD Φ.
std::vector<std::complex<double>> hermitian_spectrum(const ScreenGrid& grid,
                                                     const ScreenLayer& layer, Rng& rng) {
  const int m = grid.size;
  const double df = 1.0 / (m * grid.spacing_m);
  std::vector<std::complex<double>> c(std::size_t(m) * m);
  for (int u = 0; u < m; ++u) {
    for (int v = 0; v < m; ++v) {
      const std::size_t idx = std::size_t(u) * m + v;
      const std::size_t partner = std::size_t((m - u) % m) * m + (m - v) % m;
      if (idx > partner) continue;  // set with its partner
      const double amplitude =
          std::sqrt(screen_lattice_variance(signed_bin(u, m), signed_bin(v, m), df, layer));
      if (idx == partner) {  // DC and Nyquist bins: real
        c[idx] = amplitude * rng.normal();
      } else {
        const double re = rng.normal();
        const double im = rng.normal();
        c[idx] = amplitude * std::complex<double>(re, im) / std::numbers::sqrt2;
        c[partner] = std::conj(c[idx]);
      }
    }
  }
  return c;
}

// The subharmonics p = 1..levels of one screen: on each level the 8
// non-centre points of a 3×3 grid of spacing Δf/3^p, as 4 conjugate pairs
// (f, −f) so the sum is real: 2 Re(c (e^{2πi f·x} − 1)) with c = a (n1 + i n2)/√2,
// a² = screen_subharmonic_variance (Johansson & Gavel 1994; Schmidt 2010, listing 9.3,
// which adds all 9 points of each grid, the centre with Φ = 0).
std::vector<Subharmonic> draw_subharmonics(const ScreenGrid& grid, const ScreenLayer& layer,
                                           Rng& rng) {
  constexpr std::array<std::array<int, 2>, 4> kHalfPlane{{{1, 0}, {1, 1}, {0, 1}, {-1, 1}}};
  std::vector<Subharmonic> terms;
  double df = 1.0 / (grid.size * grid.spacing_m);
  for (int p = 1; p <= grid.subharmonic_levels; ++p) {
    df /= 3;
    for (const auto& k : kHalfPlane) {
      const double a = std::sqrt(screen_subharmonic_variance(k[0], k[1], df, layer));
      const double n1 = rng.normal();
      const double n2 = rng.normal();
      terms.push_back(
          {k[0] * df, k[1] * df, std::numbers::sqrt2 * a * std::complex<double>(n1, n2)});
    }
  }
  return terms;
}

// screen += Σ terms on the M×M grid; e^{2πi(fx x + fy y)} = ex[c] · ey[r] is
// separable, so M values per axis and term.
void add_subharmonics(const ScreenGrid& grid, std::span<const Subharmonic> terms,
                      std::span<float> screen) {
  const int m = grid.size;
  const double dx = grid.spacing_m;
  std::vector<std::complex<double>> ex(terms.size() * m), ey(terms.size() * m);
  for (std::size_t t = 0; t < terms.size(); ++t) {
    for (int i = 0; i < m; ++i) {
      const int centre = m / 2;  // x = 0 at sample M/2
      const double x = (i - centre) * dx;
      ex[t * m + i] = std::polar(1.0, 2 * kPi * terms[t].fx_per_m * x);
      ey[t * m + i] = std::polar(1.0, 2 * kPi * terms[t].fy_per_m * x);
    }
  }
  std::vector<double> row(m);
  for (int r = 0; r < m; ++r) {
    std::fill(row.begin(), row.end(), 0.0);
    for (std::size_t t = 0; t < terms.size(); ++t) {
      const std::complex<double> h = terms[t].coefficient * ey[t * m + r];
      const std::complex<double>* e = &ex[t * m];
      // Re(c (e^{iθ} − 1)): the term's value at the centre sample removed.
      const double piston = terms[t].coefficient.real();
      for (int c = 0; c < m; ++c)
        row[c] += h.real() * e[c].real() - h.imag() * e[c].imag() - piston;
    }
    for (int c = 0; c < m; ++c) screen[std::size_t(r) * m + c] += static_cast<float>(row[c]);
  }
}

}  // namespace

double screen_lattice_variance(int su, int sv, double df, const ScreenLayer& layer) {
  if (su == 0 && sv == 0) return 0;
  if (std::abs(su) <= kCellWeightedBins && std::abs(sv) <= kCellWeightedBins)
    return cell_power(su * df, sv * df, df, layer);
  return von_karman_psd(df * std::hypot(su, sv), layer) * df * df;
}

double screen_subharmonic_variance(int kx, int ky, double dp, const ScreenLayer& layer) {
  if (kx == 0 && ky == 0) return 0;
  return cell_power(kx * dp, ky * dp, dp, layer);
}

double von_karman_psd(double f_per_m, const ScreenLayer& layer) {
  const double f0 = std::isfinite(layer.outer_scale_m) ? 1.0 / layer.outer_scale_m : 0.0;
  double value = phase_psd_constant() * std::pow(layer.r0_m, -5.0 / 3.0) *
                 std::pow(f_per_m * f_per_m + f0 * f0, -11.0 / 6.0);
  if (layer.inner_scale_m > 0) {
    const double fm = 5.92 / (2 * kPi * layer.inner_scale_m);
    value *= std::exp(-(f_per_m / fm) * (f_per_m / fm));
  }
  return value;
}

double screen_structure_function(const ScreenGrid& grid, const ScreenLayer& layer, double r_m) {
  const std::array<ScreenLayer, 1> one{layer};
  validate(grid, one);
  const int m = grid.size;
  const double df = 1 / (m * grid.spacing_m);
  double d = 0;
  for (int u = 0; u < m; ++u) {
    const double fx = signed_bin(u, m) * df;
    const double weight = 1 - std::cos(2 * kPi * fx * r_m);
    for (int v = 0; v < m; ++v)
      d += 2 * screen_lattice_variance(signed_bin(u, m), signed_bin(v, m), df, layer) * weight;
  }
  double dp = df;
  for (int p = 1; p <= grid.subharmonic_levels; ++p) {
    dp /= 3;
    for (int kx = -1; kx <= 1; ++kx) {
      for (int ky = -1; ky <= 1; ++ky) {
        if (kx == 0 && ky == 0) continue;
        d += 2 * screen_subharmonic_variance(kx, ky, dp, layer) *
             (1 - std::cos(2 * kPi * kx * dp * r_m));
      }
    }
  }
  return d;
}

ScreenParts phase_screen_parts(const Device& device, const ScreenGrid& grid,
                               std::span<const ScreenLayer> layers, std::uint64_t seed,
                               FftBackend fft) {
  validate(grid, layers);
  ScreenParts parts;
  if (layers.empty()) return parts;
  const int m = grid.size;
  const std::size_t plane = std::size_t(m) * m;
  const std::int64_t pairs = (std::int64_t(layers.size()) + 1) / 2;
  Rng rng(seed);

  // Pair j: spectrum a + i b with a, b Hermitian → screens 2j (real), 2j+1 (imaginary).
  std::vector<float> spectra(std::size_t(pairs) * plane * 2);
  for (std::int64_t j = 0; j < pairs; ++j) {
    const auto a = hermitian_spectrum(grid, layers[2 * j], rng);
    std::vector<std::complex<double>> b;
    if (std::size_t(2 * j + 1) < layers.size())
      b = hermitian_spectrum(grid, layers[2 * j + 1], rng);
    float* dst = &spectra[std::size_t(j) * plane * 2];
    for (std::size_t i = 0; i < plane; ++i) {
      const std::complex<double> s = b.empty() ? a[i] : a[i] + std::complex<double>(0, 1) * b[i];
      dst[2 * i] = static_cast<float>(s.real());
      dst[2 * i + 1] = static_cast<float>(s.imag());
    }
  }
  fft2_host(fft, device, Shape{pairs, m, m}, spectra, /*inverse=*/true, kernels::FftNorm::none);

  parts.periodic.resize(layers.size() * plane);
  for (std::size_t s = 0; s < layers.size(); ++s) {
    const float* src = &spectra[(s / 2) * plane * 2 + (s % 2)];
    float* dst = &parts.periodic[s * plane];
    for (std::size_t i = 0; i < plane; ++i) dst[i] = src[2 * i];
  }
  for (const ScreenLayer& layer : layers) {
    parts.subharmonics.push_back(draw_subharmonics(grid, layer, rng));
  }
  return parts;
}

std::vector<float> phase_screens(const Device& device, const ScreenGrid& grid,
                                 std::span<const ScreenLayer> layers, std::uint64_t seed,
                                 FftBackend fft) {
  ScreenParts parts = phase_screen_parts(device, grid, layers, seed, fft);
  const std::size_t plane = std::size_t(grid.size) * grid.size;
  for (std::size_t s = 0; s < parts.subharmonics.size(); ++s) {
    add_subharmonics(grid, parts.subharmonics[s],
                     std::span<float>(&parts.periodic[s * plane], plane));
  }
  return std::move(parts.periodic);
}

std::vector<float> phase_screens(const Device& device, const ScreenGrid& grid,
                                 const ScreenLayer& layer, int count, std::uint64_t seed) {
  if (count < 0) {
    throw InvalidArgument("sim::phase_screens", "count must be ≥ 0", "ask for ≥ 0 screens");
  }
  const std::vector<ScreenLayer> layers(std::size_t(count), layer);
  return phase_screens(device, grid, layers, seed);
}

}  // namespace vkjr2::sim
