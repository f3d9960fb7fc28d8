#include <vkjr2/jr2/turbulence.hpp>
#include <vkjr2/kernels/basic.hpp>
#include <vkjr2/kernels/elementwise.hpp>
#include <vkjr2/kernels/flow.hpp>
#include <vkjr2/kernels/reduce.hpp>
#include <vkjr2/kernels/warp.hpp>
#include <vkjr2/nets/safetensors.hpp>
#include <vkjr2/sim/host_fft.hpp>
#include <vkjr2/sim/p2s_blur_model.hpp>
#include <vkjr2/sim/tilt.hpp>

#include <algorithm>
#include <array>
#include <cmath>
#include <numbers>
#include <stdexcept>
#include <string>
#include <utility>

#include "internal/text_and_draws.hpp"

namespace vkjr2::jr2 {
namespace {

constexpr const char* kKind = "vkjr2.turbulence_calibration";
constexpr double kMinCoverage = 0.02;

std::string num(double x) { return detail::number_text(x, 17); }

double parse_number(const std::map<std::string, std::string>& meta, const std::string& key,
                    const std::filesystem::path& path) {
  const auto it = meta.find(key);
  if (it == meta.end()) {
    throw Error("load turbulence calibration", path.string() + " has no metadata key '" + key + "'",
                "make the file with `vkjr2 estimate-train`");
  }
  try {
    std::size_t used = 0;
    const double v = std::stod(it->second, &used);
    if (used != it->second.size() || !std::isfinite(v)) throw std::invalid_argument("");
    return v;
  } catch (const std::exception&) {
    throw Error("load turbulence calibration",
                path.string() + ": metadata '" + key + "' = '" + it->second + "' is not a number",
                "make the file again with `vkjr2 estimate-train`");
  }
}

// The column mean of frames [T, 1, H, W] into mean [1, 1, H, W].
void temporal_mean(Stream& s, const Tensor& frames, const Tensor& mean) {
  const Shape& fs = frames.shape();
  const Tensor m = mean.reshape(Shape{fs[2] * fs[3]});
  kernels::sum_channels(s, frames.reshape(Shape{fs[0], fs[2] * fs[3]}), m);
  kernels::scale_shift(s, m, float(1.0 / double(fs[0])), 0.f, m);
}

}  // namespace

void TiltOptions::validate() const {
  const char* op = "turbulence estimate";
  if (radius < 1 || radius > 32) {
    throw InvalidArgument(op, "radius " + std::to_string(radius) + " is out of range",
                          "use a window radius in 1..32 pixels");
  }
  if (iterations < 1 || iterations > 100) {
    throw InvalidArgument(op, "iterations " + std::to_string(iterations) + " is out of range",
                          "use 1..100 Lucas–Kanade steps per pass");
  }
  if (passes < 1 || passes > 10) {
    throw InvalidArgument(op, "passes " + std::to_string(passes) + " is out of range",
                          "use 1..10 registration passes");
  }
  if (!(min_eigenvalue > 0.f) || !std::isfinite(min_eigenvalue)) {
    throw InvalidArgument(op, "min_eigenvalue " + num(min_eigenvalue) + " is not positive",
                          "use a small positive texture threshold such as 2e-5");
  }
  if (border < 0) {
    throw InvalidArgument(op, "border " + std::to_string(border) + " is negative",
                          "use 0 or more pixels");
  }
}

void SpectrumOptions::validate() const {
  const char* op = "turbulence estimate";
  if (!(band_lo > 0 && band_lo < band_hi && band_hi <= 1.0)) {
    throw InvalidArgument(op, "spectral band " + num(band_lo) + "..." + num(band_hi),
                          "use 0 < low < high ≤ 1 (fractions of the cutoff D/λ)");
  }
  if (tile < 8 || tile > 4096 || stride < 1 || stride > tile) {
    throw InvalidArgument(op,
                          "tile " + std::to_string(tile) + " px, stride " + std::to_string(stride),
                          "use tiles of 8..4096 px and a stride of 1..tile");
  }
}

namespace {

// The cutoff D/λ of the optics in cycles per pixel: IFOV / (λ/D).
double cutoff_cycles_per_px(const sim::Params& optics) {
  const double ifov = sim::pixel_pitch_m(optics) / optics.optics.focal_length_m;
  return ifov * optics.optics.aperture_m / optics.optics.wavelengths_m.front();
}

// 1-D Hann window of n points (both ends 0, as numpy.hanning).
std::vector<float> hann(int n) {
  std::vector<float> w(std::size_t(n), 1.f);
  if (n < 2) return w;
  for (int i = 0; i < n; ++i) {
    w[std::size_t(i)] = float(0.5 - 0.5 * std::cos(2.0 * std::numbers::pi * i / (n - 1)));
  }
  return w;
}

// Tile origins along an axis of `size` pixels: 0, stride, … while the tile
// fits (one tile of the whole axis when it does not).
std::vector<int> tile_origins(int size, int tile, int stride) {
  std::vector<int> o;
  if (size < tile) return {0};
  for (int x = 0; x + tile <= size; x += stride) o.push_back(x);
  return o;
}

}  // namespace

SpectrumMeasure spectral_fluctuation(std::span<const float> grey, int frames, int height, int width,
                                     const sim::Params& optics, const SpectrumOptions& options) {
  options.validate();
  const char* op = "turbulence estimate";
  TiltOptions borderless;
  borderless.border = 0;
  check_grey_video(grey, frames, height, width, borderless);
  SpectrumMeasure m;
  m.frames = frames;
  const double cutoff = cutoff_cycles_per_px(optics);
  m.band_lo_px = options.band_lo * cutoff;
  m.band_hi_px = options.band_hi * cutoff;
  const int th = std::min(height, options.tile), tw = std::min(width, options.tile);
  // The band's bins of a th×tw tile (numpy's fftfreq order).
  std::vector<std::size_t> bins;
  for (int u = 0; u < th; ++u) {
    const double fy = double(u <= (th - 1) / 2 ? u : u - th) / th;
    for (int v = 0; v < tw; ++v) {
      const double fx = double(v <= (tw - 1) / 2 ? v : v - tw) / tw;
      const double r = std::hypot(fx, fy);
      if (r >= m.band_lo_px && r < m.band_hi_px) bins.push_back(std::size_t(u) * tw + v);
    }
  }
  if (bins.size() < 8) {
    throw InvalidArgument(op,
                          "the band " + num(m.band_lo_px) + "–" + num(m.band_hi_px) +
                              " cycles/px holds " + std::to_string(bins.size()) +
                              " frequency bins of a " + std::to_string(tw) + "×" +
                              std::to_string(th) + " tile",
                          m.band_hi_px > 0.5 ? "use optics that sample the band (a finer pixel)"
                                             : "use larger frames or tiles");
  }
  const std::vector<float> wy = hann(th), wx = hann(tw);
  const std::size_t tile_px = std::size_t(th) * std::size_t(tw);
  const std::size_t plane = std::size_t(height) * std::size_t(width);
  sim::FftwFloats data(std::size_t(frames) * tile_px * 2);
  std::vector<double> per_tile;
  for (const int y0 : tile_origins(height, options.tile, options.stride)) {
    for (const int x0 : tile_origins(width, options.tile, options.stride)) {
      for (int f = 0; f < frames; ++f) {
        const float* src = grey.data() + std::size_t(f) * plane;
        double mean = 0;
        for (int y = 0; y < th; ++y) {
          for (int x = 0; x < tw; ++x)
            mean += src[std::size_t(y0 + y) * width + std::size_t(x0 + x)];
        }
        mean /= double(tile_px);
        float* dst = data.data() + std::size_t(f) * tile_px * 2;
        for (int y = 0; y < th; ++y) {
          for (int x = 0; x < tw; ++x) {
            const std::size_t i = std::size_t(y) * tw + std::size_t(x);
            const float v = src[std::size_t(y0 + y) * width + std::size_t(x0 + x)];
            dst[2 * i] = (v - float(mean)) * wy[std::size_t(y)] * wx[std::size_t(x)];
            dst[2 * i + 1] = 0.f;
          }
        }
      }
      sim::fft2_fftw(Shape{frames, th, tw}, std::span<float>(data.data(), data.size()), false);
      std::vector<double> logs;
      bool flat = false;
      for (int f = 0; f < frames; ++f) {
        const float* X = data.data() + std::size_t(f) * tile_px * 2;
        double power = 0;
        for (const std::size_t b : bins)
          power += double(X[2 * b]) * X[2 * b] + double(X[2 * b + 1]) * X[2 * b + 1];
        power /= double(bins.size());
        // A tile with no texture in the band (below 1e-10 of a unit-contrast
        // pattern's power per bin) says nothing: left out.
        if (!(power > 1e-10 * double(tile_px) * double(tile_px))) flat = true;
        logs.push_back(std::log(power));
      }
      if (flat) continue;
      double mean = 0;
      for (const double l : logs) mean += l;
      mean /= double(frames);
      double var = 0;
      for (const double l : logs) var += (l - mean) * (l - mean);
      per_tile.push_back(std::sqrt(var / double(frames)));
    }
  }
  if (per_tile.empty()) {
    throw InvalidArgument(op, "no tile of the frames has texture in the spectral band",
                          "give a video of a textured scene");
  }
  m.tiles = int(per_tile.size());
  std::sort(per_tile.begin(), per_tile.end());
  const std::size_t n = per_tile.size();
  m.fluctuation = n % 2 ? per_tile[n / 2] : 0.5 * (per_tile[n / 2 - 1] + per_tile[n / 2]);
  return m;
}

double corrected_fluctuation(const SpectrumMeasure& spectrum, double rho) {
  return spectrum.fluctuation / std::sqrt(correlated_variance_factor(spectrum.frames, rho));
}

void check_grey_video(std::span<const float> pixels, int frames, int height, int width,
                      const TiltOptions& options) {
  const char* op = "turbulence estimate";
  if (frames < 2) {
    throw InvalidArgument(op,
                          "a video of " + std::to_string(frames) + " frame has no tilt to measure",
                          "give at least 2 frames (30 for a stable estimate)");
  }
  const int inner = 2 * (options.border + 1);
  if (height < inner || width < inner) {
    throw InvalidArgument(
        op,
        "frames of " + std::to_string(width) + "×" + std::to_string(height) +
            " px leave nothing inside the " + std::to_string(options.border) + " px border",
        "use frames larger than " + std::to_string(inner) + " px or a smaller border");
  }
  const std::size_t plane = std::size_t(height) * std::size_t(width);
  const auto bad =
      std::find_if(pixels.begin(), pixels.end(), [](float x) { return !std::isfinite(x); });
  if (bad != pixels.end()) {
    throw InvalidArgument(op,
                          "frame " + std::to_string(std::size_t(bad - pixels.begin()) / plane) +
                              " holds a non-finite pixel",
                          "check the video: its pixels must be numbers");
  }
}

TiltMeasure measure_tilt(Stream& stream, const Tensor& frames, const TiltOptions& options) {
  options.validate();
  const char* op = "turbulence estimate";
  const Shape& fs = frames.shape();
  if (frames.dtype() != DType::f32 || fs.rank() != 4 || fs[1] != 1) {
    throw InvalidArgument(op, "frames " + fs.str() + " must be grey frames [T, 1, H, W]",
                          "convert the video with jr2::grey_frames");
  }
  const std::int64_t t = fs[0], h = fs[2], w = fs[3];
  check_grey_video(frames.download(), int(t), int(h), int(w), options);
  const Device& dev = stream.device();
  const Shape flow_shape{t, 2, h, w};
  Tensor a = Tensor::empty(dev, flow_shape), b = Tensor::empty(dev, flow_shape);
  const Tensor ref = Tensor::empty(dev, Shape{1, 1, h, w});
  const Tensor eig = Tensor::empty(dev, Shape{t, 1, h, w});
  const Tensor warped = Tensor::empty(dev, fs);
  kernels::fill(stream, a, 0.f);
  temporal_mean(stream, frames, ref);
  const kernels::LucasKanade lk{options.radius, options.min_eigenvalue};
  for (int pass = 0; pass < options.passes; ++pass) {
    if (pass > 0) {
      // The frames warped back by the registration so far: a sharper mean.
      kernels::warp(stream, frames, a, warped, kernels::SamplePadding::border);
      temporal_mean(stream, warped, ref);
    }
    for (int it = 0; it < options.iterations; ++it) {
      kernels::lucas_kanade_step(stream, ref, frames, a, b, eig, lk);
      std::swap(a, b);
    }
  }
  stream.run();
  const std::vector<float> flow = a.download();
  // The window's eigenvalue is the same for every frame (the reference's).
  const std::vector<float> lmin = eig.view(Shape{1, 1, h, w}).download();
  return tilt_statistics(flow, int(t), int(h), int(w), lmin, options);
}

TiltMeasure tilt_statistics(std::span<const float> flow, int frames, int height, int width,
                            std::span<const float> texture, const TiltOptions& options) {
  const char* op = "turbulence estimate";
  const std::size_t plane = std::size_t(height) * std::size_t(width);
  if (frames < 2 || flow.size() != std::size_t(frames) * 2 * plane || texture.size() != plane) {
    throw InvalidArgument(op,
                          std::to_string(flow.size()) + " flow values and " +
                              std::to_string(texture.size()) + " texture values for " +
                              std::to_string(frames) + " frames of " + std::to_string(width) + "×" +
                              std::to_string(height),
                          "pass [T, 2, H, W] flows (T ≥ 2) and an H×W texture map");
  }
  const std::int64_t t = frames, h = height, w = width;
  double sum = 0, sum_lag1 = 0;
  std::size_t used = 0;
  std::vector<double> per_pixel;
  per_pixel.reserve(plane);
  for (std::int64_t y = options.border; y < h - options.border; ++y) {
    for (std::int64_t x = options.border; x < w - options.border; ++x) {
      const std::size_t p = std::size_t(y * w + x);
      if (!(texture[p] >= options.min_eigenvalue)) continue;
      double var = 0, lag1 = 0;
      for (int axis = 0; axis < 2; ++axis) {
        double m = 0;
        for (std::int64_t f = 0; f < t; ++f) m += flow[std::size_t(2 * f + axis) * plane + p];
        m /= double(t);
        double m2 = 0, c1 = 0, prev = 0;
        for (std::int64_t f = 0; f < t; ++f) {
          const double v = flow[std::size_t(2 * f + axis) * plane + p] - m;
          m2 += v * v;
          if (f > 0) c1 += v * prev;
          prev = v;
        }
        var += m2 / double(t);
        lag1 += c1 / double(t - 1);
      }
      sum += 0.5 * var;
      sum_lag1 += 0.5 * lag1;
      per_pixel.push_back(0.5 * var);
      ++used;
    }
  }
  TiltMeasure out;
  out.frames = frames;
  out.coverage = double(used) / double(plane);
  if (out.coverage < kMinCoverage) {
    throw InvalidArgument(
        op,
        "only " + std::to_string(used) +
            " pixels have texture enough to register (the frames are nearly flat)",
        "give a video with visible detail, or lower min_eigenvalue");
  }
  if (!std::isfinite(sum) || !std::isfinite(sum_lag1)) {
    throw InvalidArgument(op, "the registration gave a non-finite displacement",
                          "check the video: its frames must be finite numbers");
  }
  out.mean_variance_px2 = sum / double(used);
  out.lag1_covariance_px2 = sum_lag1 / double(used);
  // The median: turbulence moves every pixel, a walking person or a car a
  // minority of them, whose variance would dominate the mean.
  const auto mid = per_pixel.begin() + std::ptrdiff_t(per_pixel.size() / 2);
  std::nth_element(per_pixel.begin(), mid, per_pixel.end());
  out.variance_px2 = *mid;
  return out;
}

std::vector<float> texture_map(std::span<const float> image, int height, int width, int radius) {
  const std::size_t plane = std::size_t(height) * std::size_t(width);
  if (height < 1 || width < 1 || image.size() != plane || radius < 0) {
    throw InvalidArgument("texture_map", std::to_string(image.size()) + " values for " +
                                             std::to_string(width) + "×" + std::to_string(height) +
                                             ", radius " + std::to_string(radius));
  }
  // Σ of gx², gx·gy, gy² over the window by summed-area tables.
  const std::size_t sw = std::size_t(width) + 1;
  std::vector<double> sxx((std::size_t(height) + 1) * sw), sxy(sxx.size()), syy(sxx.size());
  const auto at = [&](int y, int x) { return double(image[std::size_t(y) * width + x]); };
  for (int y = 0; y < height; ++y) {
    for (int x = 0; x < width; ++x) {
      const double gx = 0.5 * (at(y, std::min(x + 1, width - 1)) - at(y, std::max(x - 1, 0)));
      const double gy = 0.5 * (at(std::min(y + 1, height - 1), x) - at(std::max(y - 1, 0), x));
      const std::size_t i = (std::size_t(y) + 1) * sw + std::size_t(x) + 1;
      sxx[i] = gx * gx + sxx[i - 1] + sxx[i - sw] - sxx[i - sw - 1];
      sxy[i] = gx * gy + sxy[i - 1] + sxy[i - sw] - sxy[i - sw - 1];
      syy[i] = gy * gy + syy[i - 1] + syy[i - sw] - syy[i - sw - 1];
    }
  }
  std::vector<float> out(plane);
  for (int y = 0; y < height; ++y) {
    for (int x = 0; x < width; ++x) {
      const std::size_t y0 = std::size_t(std::max(y - radius, 0));
      const std::size_t y1 = std::size_t(std::min(y + radius, height - 1)) + 1;
      const std::size_t x0 = std::size_t(std::max(x - radius, 0));
      const std::size_t x1 = std::size_t(std::min(x + radius, width - 1)) + 1;
      const double n = double((y1 - y0) * (x1 - x0));
      const auto box = [&](const std::vector<double>& s) {
        return (s[y1 * sw + x1] - s[y0 * sw + x1] - s[y1 * sw + x0] + s[y0 * sw + x0]) / n;
      };
      const double a = box(sxx), c = box(sxy), d = box(syy);
      const double half_diff = 0.5 * (a - d);
      out[std::size_t(y) * width + x] =
          float(0.5 * (a + d) - std::sqrt(half_diff * half_diff + c * c));
    }
  }
  return out;
}

double correlated_variance_factor(int frames, double rho) {
  if (frames < 2 || !(rho >= 0.0 && rho < 1.0)) {
    throw InvalidArgument("correlated_variance_factor",
                          "frames " + std::to_string(frames) + ", rho " + num(rho),
                          "use at least 2 frames and 0 ≤ rho < 1");
  }
  double s = 1.0, rk = 1.0;
  for (int k = 1; k < frames; ++k) {
    rk *= rho;
    s += 2.0 * (1.0 - double(k) / frames) * rk;
  }
  return 1.0 - s / frames;
}

double raw_d_over_r0(double variance_px2, int frames, const sim::Params& optics, double rho) {
  // Z-tilt angle variance at D/r0 = 1, in pixels²: 0.182 (λ/D)² / IFOV².
  sim::Params p = optics;
  p.path.strength = sim::Strength::r0;
  p.path.r0_m = p.optics.aperture_m;  // D/r0 = 1 at the first wavelength
  p.path.r0_wavelength_m = 0;
  const double ifov = sim::pixel_pitch_m(p) / p.optics.focal_length_m;
  const double unit_px2 = sim::tilt_angle_variance_rad2(p, 0) / (ifov * ifov);
  const double corrected = variance_px2 / correlated_variance_factor(frames, rho);
  return std::pow(corrected / unit_px2, 3.0 / 5.0);
}

TurbulenceCalibration TurbulenceCalibration::identity() { return {}; }

std::string TurbulenceCalibration::cues() const {
  if (uses_tilt() && uses_spectrum()) return "tilt+spectrum";
  return uses_spectrum() ? "spectrum" : "tilt";
}

void TurbulenceCalibration::save(const std::filesystem::path& path) const {
  std::map<std::string, std::string> meta = metadata;
  meta["kind"] = kKind;
  meta["gain"] = num(gain);
  meta["exponent"] = num(exponent);
  meta["tilt_correlation"] = num(tilt_correlation);
  meta["registration"] = registration;
  meta["tilt.radius"] = std::to_string(tilt.radius);
  meta["tilt.iterations"] = std::to_string(tilt.iterations);
  meta["tilt.passes"] = std::to_string(tilt.passes);
  meta["tilt.min_eigenvalue"] = num(tilt.min_eigenvalue);
  meta["tilt.border"] = std::to_string(tilt.border);
  meta["cues"] = cues();
  meta["blur_exponent"] = num(blur_exponent);
  meta["blur_correlation"] = num(blur_correlation);
  meta["spectrum.band_lo"] = num(spectrum.band_lo);
  meta["spectrum.band_hi"] = num(spectrum.band_hi);
  meta["spectrum.tile"] = std::to_string(spectrum.tile);
  meta["spectrum.stride"] = std::to_string(spectrum.stride);
  const std::vector<float> values{float(std::log(gain)), float(exponent), float(blur_exponent)};
  const std::vector<nets::SafetensorsRecord> records{
      nets::SafetensorsRecord::f32("log_gain_exponents", {3}, values)};
  nets::write_safetensors(path, records, meta);
}

TurbulenceCalibration TurbulenceCalibration::load(const std::filesystem::path& path) {
  const nets::SafetensorsFile file = nets::read_safetensors(path);
  const auto kind = file.metadata.find("kind");
  if (kind == file.metadata.end() || kind->second != kKind) {
    throw Error(
        "load turbulence calibration",
        path.string() + " is not a turbulence calibration (metadata kind is not '" + kKind + "')",
        "give the file `vkjr2 estimate-train` wrote");
  }
  TurbulenceCalibration c;
  c.metadata = file.metadata;
  c.gain = parse_number(file.metadata, "gain", path);
  c.exponent = parse_number(file.metadata, "exponent", path);
  c.tilt_correlation = parse_number(file.metadata, "tilt_correlation", path);
  c.tilt.radius = int(parse_number(file.metadata, "tilt.radius", path));
  c.tilt.iterations = int(parse_number(file.metadata, "tilt.iterations", path));
  c.tilt.passes = int(parse_number(file.metadata, "tilt.passes", path));
  c.tilt.min_eigenvalue = float(parse_number(file.metadata, "tilt.min_eigenvalue", path));
  c.tilt.border = int(parse_number(file.metadata, "tilt.border", path));
  // A calibration without the spectral keys is a tilt-only one (blur_exponent stays 0).
  if (file.metadata.contains("cues")) {
    c.blur_exponent = parse_number(file.metadata, "blur_exponent", path);
    c.blur_correlation = parse_number(file.metadata, "blur_correlation", path);
    c.spectrum.band_lo = parse_number(file.metadata, "spectrum.band_lo", path);
    c.spectrum.band_hi = parse_number(file.metadata, "spectrum.band_hi", path);
    c.spectrum.tile = int(parse_number(file.metadata, "spectrum.tile", path));
    c.spectrum.stride = int(parse_number(file.metadata, "spectrum.stride", path));
    if (file.metadata.at("cues") != c.cues() ||
        !(c.blur_correlation >= 0 && c.blur_correlation < 1)) {
      throw Error("load turbulence calibration",
                  path.string() + " names the cues '" + file.metadata.at("cues") +
                      "' but holds exponents " + num(c.exponent) + " (tilt), " +
                      num(c.blur_exponent) + " (spectrum) and blur_correlation " +
                      num(c.blur_correlation),
                  "make the file again with `vkjr2 estimate-train`");
    }
  }
  const auto reg = file.metadata.find("registration");
  if (reg == file.metadata.end() || (reg->second != "dis" && reg->second != "lk")) {
    throw Error("load turbulence calibration",
                path.string() + " names no registration ('dis' or 'lk')",
                "make the file again with `vkjr2 estimate-train`");
  }
  c.registration = reg->second;
  if (!(c.gain > 0) || !(c.tilt_correlation >= 0 && c.tilt_correlation < 1)) {
    throw Error("load turbulence calibration",
                path.string() + " holds gain " + num(c.gain) + " and tilt_correlation " +
                    num(c.tilt_correlation),
                "make the file again with `vkjr2 estimate-train`");
  }
  try {
    c.tilt.validate();
    c.spectrum.validate();
  } catch (const InvalidArgument& e) {
    throw Error("load turbulence calibration", path.string() + ": " + e.problem(),
                "make the file again with `vkjr2 estimate-train`");
  }
  for (const char* k :
       {"kind", "gain", "exponent", "tilt_correlation", "registration", "tilt.radius",
        "tilt.iterations", "tilt.passes", "tilt.min_eigenvalue", "tilt.border", "cues",
        "blur_exponent", "blur_correlation", "spectrum.band_lo", "spectrum.band_hi",
        "spectrum.tile", "spectrum.stride"}) {
    c.metadata.erase(k);
  }
  return c;
}

TurbulenceEstimate estimate_turbulence(Stream& stream, const Tensor& frames,
                                       const sim::Params& optics,
                                       const TurbulenceCalibration& calibration) {
  if (calibration.registration != "lk") {
    throw InvalidArgument("turbulence estimate",
                          "the calibration was fitted on '" + calibration.registration +
                              "' registration, this measures with 'lk'",
                          "use a calibration fitted with --registration lk");
  }
  TiltMeasure tilt;
  if (calibration.uses_tilt()) tilt = measure_tilt(stream, frames, calibration.tilt);
  SpectrumMeasure spectrum;
  if (calibration.uses_spectrum()) {
    const Shape& s = frames.shape();
    spectrum = spectral_fluctuation(frames.download(), int(s[0]), int(s[2]), int(s[3]), optics,
                                    calibration.spectrum);
  }
  return estimate_turbulence(tilt, spectrum, optics, calibration);
}

TurbulenceEstimate estimate_turbulence(const TiltMeasure& tilt, const SpectrumMeasure& spectrum,
                                       const sim::Params& optics,
                                       const TurbulenceCalibration& calibration) {
  const char* op = "turbulence estimate";
  TurbulenceEstimate e;
  e.tilt = tilt;
  e.spectrum = spectrum;
  double d = calibration.gain;
  if (calibration.uses_tilt() || tilt.frames > 0) {
    if (tilt.frames < 2) {
      throw InvalidArgument(op, "the calibration uses the tilt, which was not measured",
                            "measure the tilt of the video");
    }
    e.raw_d_over_r0 =
        raw_d_over_r0(e.tilt.variance_px2, e.tilt.frames, optics, calibration.tilt_correlation);
    d *= std::pow(e.raw_d_over_r0, calibration.exponent);
  }
  if (calibration.uses_spectrum() || spectrum.frames > 0) {
    if (spectrum.frames < 2) {
      throw InvalidArgument(op, "the calibration uses the spectral cue, which was not measured",
                            "measure it with spectral_fluctuation");
    }
    e.blur = corrected_fluctuation(spectrum, calibration.blur_correlation);
    d *= std::pow(e.blur, calibration.blur_exponent);
  }
  e.d_over_r0 = d;
  e.r0_m = optics.optics.aperture_m / e.d_over_r0;
  return e;
}

TurbulenceEstimate estimate_turbulence(const TiltMeasure& tilt, const sim::Params& optics,
                                       const TurbulenceCalibration& calibration) {
  return estimate_turbulence(tilt, SpectrumMeasure{}, optics, calibration);
}

TurbulenceCalibration fit_calibration(std::span<const double> raw, std::span<const double> truth,
                                      const TiltOptions& tilt, double tilt_correlation,
                                      const std::string& registration) {
  TurbulenceCalibration base;
  base.tilt = tilt;
  base.tilt_correlation = tilt_correlation;
  base.registration = registration;
  return fit_calibration(base, raw, {}, truth);
}

TurbulenceCalibration fit_calibration(const TurbulenceCalibration& base,
                                      std::span<const double> raw, std::span<const double> blur,
                                      std::span<const double> truth) {
  const char* op = "fit turbulence calibration";
  const bool t = base.uses_tilt(), b = base.uses_spectrum();
  if (!t && !b) throw InvalidArgument(op, "no cue to fit", "use the tilt, the spectrum or both");
  const std::size_t n = truth.size(), k = 1 + (t ? 1 : 0) + (b ? 1 : 0);
  if ((t && raw.size() != n) || (b && blur.size() != n) || n < k + 1) {
    throw InvalidArgument(op,
                          std::to_string(n) + " true values for " + std::to_string(raw.size()) +
                              " tilt and " + std::to_string(blur.size()) + " spectral measures",
                          "give at least " + std::to_string(k + 1) + " videos of known D/r0");
  }
  // Normal equations of log D/r0 = c0 + c1 · log raw + c2 · log blur.
  std::array<std::array<double, 4>, 3> a{};  // [k × k | rhs]
  for (std::size_t i = 0; i < n; ++i) {
    std::array<double, 3> x{1.0, 0, 0};
    std::size_t j = 1;
    const auto positive = [&](double v, const char* what) {
      if (!(v > 0) || !std::isfinite(v)) {
        throw InvalidArgument(op, "video " + std::to_string(i) + ": " + what + " " + num(v),
                              "every value must be positive");
      }
      return std::log(v);
    };
    if (t) x[j++] = positive(raw[i], "raw D/r0");
    if (b) x[j++] = positive(blur[i], "spectral fluctuation");
    const double y = positive(truth[i], "true D/r0");
    for (std::size_t r = 0; r < k; ++r) {
      for (std::size_t c = 0; c < k; ++c) a[r][c] += x[r] * x[c];
      a[r][3] += x[r] * y;
    }
  }
  // Gauss–Jordan with partial pivoting; a pivot below 1e-9 of the diagonal's
  // scale means the cues do not vary (independently).
  double scale = 0;
  for (std::size_t r = 0; r < k; ++r) scale = std::max(scale, std::abs(a[r][r]));
  for (std::size_t c = 0; c < k; ++c) {
    std::size_t p = c;
    for (std::size_t r = c + 1; r < k; ++r) {
      if (std::abs(a[r][c]) > std::abs(a[p][c])) p = r;
    }
    if (!(std::abs(a[p][c]) > 1e-9 * scale)) {
      throw InvalidArgument(op, "the measured cues do not vary (independently) over the videos",
                            "calibrate on a range of strengths");
    }
    std::swap(a[c], a[p]);
    for (std::size_t r = 0; r < k; ++r) {
      if (r == c) continue;
      const double f = a[r][c] / a[c][c];
      for (std::size_t q = c; q < k; ++q) a[r][q] -= f * a[c][q];
      a[r][3] -= f * a[c][3];
    }
  }
  TurbulenceCalibration c = base;
  c.metadata.clear();
  std::size_t j = 0;
  c.gain = std::exp(a[j][3] / a[j][j]);
  ++j;
  c.exponent = t ? a[j][3] / a[j][j] : 0.0;
  if (t) ++j;
  c.blur_exponent = b ? a[j][3] / a[j][j] : 0.0;
  return c;
}

std::vector<float> grey_frames(std::span<const float> rgb, int frames, int channels, int height,
                               int width, float range) {
  const std::size_t plane = std::size_t(height) * std::size_t(width);
  if (frames < 1 || channels < 1 || rgb.size() != std::size_t(frames) * channels * plane) {
    throw InvalidArgument("grey_frames", std::to_string(rgb.size()) + " values for " +
                                             std::to_string(frames) + " frames of " +
                                             std::to_string(channels) + "×" +
                                             std::to_string(height) + "×" + std::to_string(width));
  }
  std::vector<float> out(std::size_t(frames) * plane);
  const float scale = 1.f / (range * float(channels));
  for (int f = 0; f < frames; ++f) {
    for (std::size_t p = 0; p < plane; ++p) {
      float s = 0;
      for (int c = 0; c < channels; ++c) s += rgb[(std::size_t(f) * channels + c) * plane + p];
      out[std::size_t(f) * plane + p] = s * scale;
    }
  }
  return out;
}

SimulatedVideo simulate_video(const Device& device, const Tensor& scene, const sim::Params& params,
                              const sim::SimOptions& options,
                              const std::vector<std::shared_ptr<const sim::BlurModel>>& blur,
                              std::uint64_t seed, int frames) {
  const Shape& s = scene.shape();
  SimulatedVideo v;
  v.frames = frames;
  v.height = int(s[2]);
  v.width = int(s[3]);
  sim::Simulator simulator(device, params, blur, options);
  simulator.reset(seed);
  const Tensor y = Tensor::empty(device, s);
  Stream stream(device);
  for (int f = 0; f < frames; ++f) {
    simulator.frame(stream, scene, y);
    stream.run();
    const std::vector<float> g = grey_frames(y.download(), 1, int(s[1]), v.height, v.width, 1.f);
    v.grey.insert(v.grey.end(), g.begin(), g.end());
    const std::vector<float> fl = simulator.flow().download();
    v.flow.insert(v.flow.end(), fl.begin(), fl.end());
  }
  return v;
}

std::filesystem::path default_turbulence_calibration_path() {
  return sim::default_blur_model_path().parent_path() / "turbulence_estimator.safetensors";
}

}  // namespace vkjr2::jr2
