#include <vkjr2/kernels/fft.hpp>
#include <vkjr2/runtime/error.hpp>
#include <vkjr2/runtime/stream.hpp>
#include <vkjr2/sim/params.hpp>
#include <vkjr2/sim/psf_basis.hpp>
#include <vkjr2/sim/zernike.hpp>

#include <Eigen/Dense>

#include <algorithm>
#include <cmath>
#include <map>
#include <string>

namespace vkjr2::sim {
namespace {

using RowMatrix = Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>;

std::size_t sz(std::int64_t v) { return static_cast<std::size_t>(v); }

void check_sampling(const PsfSampling& s) {
  const char* op = "sim::psf_grid";
  if (!std::isfinite(s.nyquist) || s.nyquist <= 0)
    throw InvalidArgument(op, "Nyquist ratio " + std::to_string(s.nyquist) + " is not positive",
                          "pass q = λ f / (2 D p) from sim::derive(params).channels[c].nyquist");
  if (s.size < 1 || s.size % 2 == 0)
    throw InvalidArgument(
        op, "crop size " + std::to_string(s.size) + " is not a positive odd number",
        "use an odd size such as 33 so that the optical axis is the centre pixel");
  if (s.j_max < 4 || s.j_max > kMaxZernikeModes)
    throw InvalidArgument(
        op,
        "j_max " + std::to_string(s.j_max) + " is outside 4.." + std::to_string(kMaxZernikeModes),
        "the PSF needs at least defocus (Noll j = 4)");
  if (!std::isfinite(s.min_pupil_px) || s.min_pupil_px < 4 || s.min_pupil_px > 4096)
    throw InvalidArgument(op,
                          "min_pupil_px " + std::to_string(s.min_pupil_px) + " is outside 4..4096",
                          "64 samples across the pupil resolve 36 Zernike modes well");
}

}  // namespace

PsfGrid psf_grid(const PsfSampling& sampling) {
  check_sampling(sampling);
  const double q = sampling.nyquist;
  PsfGrid g;
  // N = 2 q m · diameter_px must hold the pupil (N ≥ diameter_px): m ≥ 1/(2q).
  g.oversample = std::max(1, static_cast<int>(std::ceil(1.0 / (2.0 * q) - 1e-12)));
  const double per_pupil_px = 2.0 * q * g.oversample;
  auto n = static_cast<std::int64_t>(std::ceil(per_pupil_px * sampling.min_pupil_px - 1e-9));
  n = std::max<std::int64_t>(n, std::int64_t(g.oversample) * sampling.size);
  while (!kernels::fft_supported_length(n) || n % g.oversample != 0) ++n;
  if (n > 4096)
    throw InvalidArgument("sim::psf_grid",
                          "the PSF needs a " + std::to_string(n) + "-point FFT (Nyquist ratio " +
                              std::to_string(q) + ", crop " + std::to_string(sampling.size) + ")",
                          "use a smaller crop, a smaller min_pupil_px or a sampling closer to 1");
  g.fft_size = static_cast<int>(n);
  g.diameter_px = double(n) / per_pupil_px;
  return g;
}

struct WavePsf::Impl {
  Impl(const Device& d, const PsfSampling& s) : device(d), sampling(s), grid(psf_grid(s)) {}
  Device device;
  PsfSampling sampling;
  PsfGrid grid;
  int batch = 1;                    // FFTs per dispatch chunk
  std::vector<std::int64_t> pupil;  // flat indices of the samples inside the pupil
  RowMatrix modes;                  // [modes, pupil.size()]: Z_4.. at those samples
  // Plans by batch size (the full chunk and a shorter last one), built on first use.
  mutable std::map<int, kernels::FftPlan> plans;
  const kernels::FftPlan& plan(int b) const {
    auto it = plans.find(b);
    if (it == plans.end()) {
      const int n = grid.fft_size;
      it =
          plans
              .try_emplace(b, device, Shape{b, n, n}, kernels::FftKind::c2c, kernels::FftNorm::none)
              .first;
    }
    return it->second;
  }
  std::vector<std::int64_t> crop;    // flat FFT bin of each crop pixel (fftshift + subsample)
  std::vector<std::int64_t> period;  // flat FFT bin of each pitch sample in one period
};

WavePsf::WavePsf(const Device& device, const PsfSampling& sampling)
    : impl_(std::make_unique<Impl>(device, sampling)) {
  Impl& m = *impl_;
  const int n = m.grid.fft_size;
  const PupilGrid pg{n, m.grid.diameter_px};
  const std::vector<double> mask = pupil_mask(pg);
  for (std::size_t i = 0; i < mask.size(); ++i)
    if (mask[i] > 0) m.pupil.push_back(std::int64_t(i));
  const std::vector<double> z = zernike_modes(4, sampling.j_max, pg);
  const int modes = sampling.j_max - 3;
  const std::size_t plane = sz(std::int64_t(n) * n);
  m.modes.resize(modes, Eigen::Index(m.pupil.size()));
  for (int k = 0; k < modes; ++k)
    for (std::size_t i = 0; i < m.pupil.size(); ++i)
      m.modes(k, Eigen::Index(i)) = z[plane * sz(k) + sz(m.pupil[i])];

  // Chunks of ≤ 32 MiB of complex field (and ≤ 256 images).
  const std::int64_t bytes = std::int64_t(plane) * 8;
  m.batch = static_cast<int>(std::clamp<std::int64_t>((32ll << 20) / bytes, 1, 256));

  // Bin of detector offset d (pixels, d = 0 the axis) is (d · oversample) mod n.
  const int s = sampling.size, h = s / 2, ov = m.grid.oversample;
  auto bin = [n, ov](int d) { return ((std::int64_t(d) * ov) % n + n) % n; };
  for (int r = -h; r <= h; ++r)
    for (int c = -h; c <= h; ++c) m.crop.push_back(bin(r) * n + bin(c));
  const int p = m.grid.period_px();
  for (int r = 0; r < p; ++r)
    for (int c = 0; c < p; ++c) m.period.push_back(bin(r) * n + bin(c));
}

WavePsf::~WavePsf() = default;
WavePsf::WavePsf(WavePsf&&) noexcept = default;
WavePsf& WavePsf::operator=(WavePsf&&) noexcept = default;

const PsfSampling& WavePsf::sampling() const { return impl_->sampling; }
const PsfGrid& WavePsf::grid() const { return impl_->grid; }
int WavePsf::modes() const { return impl_->sampling.j_max - 3; }

void WavePsf::compute(std::span<const double> coeffs, std::span<float> psfs,
                      std::span<double> energy_in_crop) const {
  const Impl& m = *impl_;
  const int modes = this->modes();
  const std::size_t crop_px = sz(std::int64_t(m.sampling.size) * m.sampling.size);
  if (coeffs.size() % sz(modes) != 0)
    throw InvalidArgument("sim::WavePsf::compute",
                          std::to_string(coeffs.size()) + " coefficients are not a multiple of " +
                              std::to_string(modes) + " (a_4..a_" +
                              std::to_string(m.sampling.j_max) + " per PSF)",
                          "pass count × (j_max − 3) values, row-major");
  const std::size_t count = coeffs.size() / sz(modes);
  if (psfs.size() != count * crop_px || (!energy_in_crop.empty() && energy_in_crop.size() != count))
    throw InvalidArgument("sim::WavePsf::compute",
                          "output sizes " + std::to_string(psfs.size()) + " / " +
                              std::to_string(energy_in_crop.size()) + " do not match " +
                              std::to_string(count) + " PSFs of " + std::to_string(crop_px) +
                              " pixels",
                          "size psfs to count × S² and energy_in_crop to count (or empty)");
  for (const double a : coeffs)
    if (!std::isfinite(a))
      throw InvalidArgument("sim::WavePsf::compute", "a coefficient is not finite",
                            "check the aberrations passed in");

  const int n = m.grid.fft_size;
  const std::size_t plane = sz(std::int64_t(n) * n);
  Stream stream(m.device);
  std::vector<float> host, spectrum;
  for (std::size_t first = 0; first < count; first += sz(m.batch)) {
    const std::size_t b = std::min(sz(m.batch), count - first);
    const Tensor field = Tensor::empty(m.device, Shape{std::int64_t(b), n, n, 2});
    host.resize(plane * 2 * b);
    spectrum.resize(host.size());
    const Eigen::Map<const RowMatrix> a(coeffs.data() + first * sz(modes), Eigen::Index(b), modes);
    const RowMatrix phase = a * m.modes;  // [b, pupil samples]
    std::fill(host.begin(), host.end(), 0.f);
    for (std::size_t i = 0; i < b; ++i) {
      float* f = host.data() + i * plane * 2;
      for (std::size_t p = 0; p < m.pupil.size(); ++p) {
        const double ph = phase(Eigen::Index(i), Eigen::Index(p));
        f[2 * sz(m.pupil[p])] = static_cast<float>(std::cos(ph));
        f[2 * sz(m.pupil[p]) + 1] = static_cast<float>(std::sin(ph));
      }
    }
    field.upload(host);
    m.plan(int(b)).forward(stream, field, field);
    stream.run();
    field.download(spectrum);
    for (std::size_t i = 0; i < b; ++i) {
      const float* x = spectrum.data() + i * plane * 2;
      auto power = [x](std::int64_t k) {
        const double re = x[2 * k], im = x[2 * k + 1];
        return re * re + im * im;
      };
      float* out = psfs.data() + (first + i) * crop_px;
      double inside = 0;
      for (std::size_t p = 0; p < crop_px; ++p) inside += power(m.crop[p]);
      for (std::size_t p = 0; p < crop_px; ++p)
        out[p] = static_cast<float>(power(m.crop[p]) / inside);
      if (!energy_in_crop.empty()) {
        double total = 0;
        for (const std::int64_t k : m.period) total += power(k);
        energy_in_crop[first + i] = inside / total;
      }
    }
  }
}

std::vector<float> WavePsf::compute(std::span<const double> coeffs) const {
  const std::size_t count = coeffs.size() / sz(modes());
  std::vector<float> out(count * sz(std::int64_t(impl_->sampling.size) * impl_->sampling.size));
  compute(coeffs, out);
  return out;
}

std::vector<double> draw_aberrations(Rng& rng, const NollSampler& noll, double d_over_r0_min,
                                     double d_over_r0_max, int count) {
  if (!(d_over_r0_min >= 0) || !(d_over_r0_max >= d_over_r0_min) || !std::isfinite(d_over_r0_max))
    throw InvalidArgument("sim::draw_aberrations",
                          "D/r0 range [" + std::to_string(d_over_r0_min) + ", " +
                              std::to_string(d_over_r0_max) + "] is empty or negative",
                          "pass 0 ≤ d_over_r0_min ≤ d_over_r0_max");
  if (noll.j_max() < 4 || count < 0)
    throw InvalidArgument("sim::draw_aberrations", "needs j_max ≥ 4 and count ≥ 0",
                          "build the NollSampler with j_max ≥ 4");
  const int modes = noll.j_max() - 3;
  std::vector<double> out(sz(count) * sz(modes));
  std::vector<double> a(sz(noll.modes()));
  for (int i = 0; i < count; ++i) {
    const double d = d_over_r0_min + (d_over_r0_max - d_over_r0_min) * rng.uniform();
    noll.sample(rng, d, a);
    std::copy(a.begin() + 2, a.end(), out.begin() + std::ptrdiff_t(sz(i) * sz(modes)));
  }
  return out;
}

int PsfBasis::count() const { return static_cast<int>(variances.size()); }

PsfBasis psf_basis_from_samples(std::span<const float> samples, int size, int count, double nyquist,
                                int j_max) {
  const char* op = "sim::psf_basis_from_samples";
  if (size < 1 || size % 2 == 0)
    throw InvalidArgument(op, "size " + std::to_string(size) + " is not a positive odd number",
                          "use an odd crop size");
  const auto d = Eigen::Index(size) * size;
  if (samples.size() % sz(d) != 0 || samples.size() / sz(d) < 2)
    throw InvalidArgument(op,
                          std::to_string(samples.size()) + " values are not ≥ 2 PSFs of " +
                              std::to_string(d) + " pixels",
                          "pass M × S² values with M ≥ 2");
  const auto m = Eigen::Index(samples.size() / sz(d));
  if (count < 1 || count - 1 > std::min<Eigen::Index>(m - 1, d))
    throw InvalidArgument(op,
                          "K = " + std::to_string(count) +
                              " components need K − 1 ≤ min(M − 1, S²) = " +
                              std::to_string(std::min<Eigen::Index>(m - 1, d)),
                          "draw more samples or ask for fewer components");
  const Eigen::Map<const Eigen::Matrix<float, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>> raw(
      samples.data(), m, d);
  RowMatrix x = raw.cast<double>();
  const Eigen::RowVectorXd mean = x.colwise().mean();
  x.rowwise() -= mean;

  const int pcs = count - 1;
  Eigen::MatrixXd vectors(d, pcs);  // columns: PCs, descending variance
  Eigen::VectorXd values(pcs);
  const double dof = double(m - 1);
  if (pcs > 0) {
    if (m >= d) {  // covariance d × d
      const Eigen::MatrixXd cov = (x.transpose() * x) / dof;
      const Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> es(cov);
      if (es.info() != Eigen::Success)
        throw Error(op, "the covariance eigendecomposition did not converge", "check the samples");
      for (int k = 0; k < pcs; ++k) {
        vectors.col(k) = es.eigenvectors().col(d - 1 - k);
        values(k) = es.eigenvalues()(d - 1 - k);
      }
    } else {  // Gram m × m: X Xᵀ u = λ u  →  PC ∝ Xᵀ u
      const Eigen::MatrixXd gram = (x * x.transpose()) / dof;
      const Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> es(gram);
      if (es.info() != Eigen::Success)
        throw Error(op, "the Gram eigendecomposition did not converge", "check the samples");
      for (int k = 0; k < pcs; ++k) {
        Eigen::VectorXd v = x.transpose() * es.eigenvectors().col(m - 1 - k);
        const double norm = v.norm();
        vectors.col(k) = norm > 0 ? Eigen::VectorXd(v / norm) : v;
        values(k) = es.eigenvalues()(m - 1 - k);
      }
    }
  }

  PsfBasis basis;
  basis.size = size;
  basis.nyquist = nyquist;
  basis.j_max = j_max;
  basis.kernels.resize(sz(count) * sz(d));
  basis.variances.assign(sz(count), 0.f);
  const double mean_sum = mean.sum();
  for (Eigen::Index i = 0; i < d; ++i)
    basis.kernels[sz(i)] = static_cast<float>(mean(i) / mean_sum);
  for (int k = 0; k < pcs; ++k) {
    Eigen::VectorXd v = vectors.col(k);
    Eigen::Index big = 0;
    v.cwiseAbs().maxCoeff(&big);
    if (v(big) < 0) v = -v;  // a deterministic sign
    v /= v.norm();
    float* out = basis.kernels.data() + sz(k + 1) * sz(d);
    for (Eigen::Index i = 0; i < d; ++i) out[i] = static_cast<float>(v(i));
    basis.variances[sz(k + 1)] = static_cast<float>(std::max(0.0, values(k)));
  }
  return basis;
}

PsfBasis make_psf_basis(const Device& device, double nyquist, int j_max,
                        const PsfBasisConfig& config) {
  const int drawn = std::max(j_max, config.residual_j_max);
  const WavePsf psf(device, PsfSampling{nyquist, config.size, drawn, config.min_pupil_px});
  const NollSampler noll(drawn);
  Rng rng(config.seed);
  const std::vector<double> a =
      draw_aberrations(rng, noll, config.d_over_r0_min, config.d_over_r0_max, config.samples);
  return psf_basis_from_samples(psf.compute(a), config.size, config.count, nyquist, j_max);
}

std::vector<double> leading_columns(std::span<const double> rows, int columns, int keep) {
  if (columns < 1 || keep < 0 || keep > columns || rows.size() % sz(columns) != 0)
    throw InvalidArgument("sim::leading_columns",
                          "needs 0 ≤ keep ≤ columns and whole rows of `columns` values",
                          "pass the draws' own column count");
  const std::size_t n = rows.size() / sz(columns);
  std::vector<double> out(n * sz(keep));
  for (std::size_t i = 0; i < n; ++i)
    std::copy_n(rows.begin() + std::ptrdiff_t(i * sz(columns)), keep,
                out.begin() + std::ptrdiff_t(i * sz(keep)));
  return out;
}

namespace {
using FloatMatrix = Eigen::Matrix<float, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>;

std::size_t image_count(const PsfBasis& basis, std::size_t values, std::size_t per_image,
                        const char* op) {
  if (basis.size < 1 || basis.kernels.size() != sz(basis.count()) * sz(basis.size) * sz(basis.size))
    throw InvalidArgument(op, "the basis is empty or its kernels do not match [K, S, S]",
                          "build it with make_psf_basis or load it with load_p2s_model");
  if (values % per_image != 0)
    throw InvalidArgument(
        op, std::to_string(values) + " values are not a multiple of " + std::to_string(per_image),
        "pass whole images (S²) or whole coefficient rows (K)");
  return values / per_image;
}
}  // namespace

std::vector<float> project(const PsfBasis& basis, std::span<const float> psfs) {
  const auto d = Eigen::Index(basis.size) * basis.size;
  const auto k = Eigen::Index(basis.count());
  const auto n = Eigen::Index(image_count(basis, psfs.size(), sz(d), "sim::project"));
  const Eigen::Map<const FloatMatrix> h(psfs.data(), n, d);
  const Eigen::Map<const FloatMatrix> psi(basis.kernels.data(), k, d);
  FloatMatrix centred = h;
  centred.rowwise() -= psi.row(0);
  FloatMatrix beta = centred * psi.transpose();
  beta.col(0).setOnes();
  return {beta.data(), beta.data() + beta.size()};
}

std::vector<float> reconstruct(const PsfBasis& basis, std::span<const float> betas, int terms) {
  const auto d = Eigen::Index(basis.size) * basis.size;
  const auto k = Eigen::Index(basis.count());
  const auto n = Eigen::Index(image_count(basis, betas.size(), sz(k), "sim::reconstruct"));
  const Eigen::Index t = terms <= 0 ? k : std::min<Eigen::Index>(terms, k);
  const Eigen::Map<const FloatMatrix> b(betas.data(), n, k);
  const Eigen::Map<const FloatMatrix> psi(basis.kernels.data(), k, d);
  const FloatMatrix h = b.leftCols(t) * psi.topRows(t);
  return {h.data(), h.data() + h.size()};
}

double mean_relative_l2(std::span<const float> a, std::span<const float> b, int image_size) {
  if (image_size < 1 || a.size() != b.size() || a.size() % sz(image_size) != 0 || a.empty())
    throw InvalidArgument("sim::mean_relative_l2",
                          "sizes " + std::to_string(a.size()) + " and " + std::to_string(b.size()) +
                              " are not equal whole images of " + std::to_string(image_size),
                          "pass two stacks of the same images");
  const std::size_t n = a.size() / sz(image_size);
  double total = 0;
  for (std::size_t i = 0; i < n; ++i) {
    double num = 0, den = 0;
    for (std::size_t p = i * sz(image_size); p < (i + 1) * sz(image_size); ++p) {
      const double diff = double(a[p]) - b[p];
      num += diff * diff;
      den += double(b[p]) * b[p];
    }
    total += std::sqrt(num / den);
  }
  return total / double(n);
}

}  // namespace vkjr2::sim
