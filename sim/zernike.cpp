#include <vkjr2/runtime/error.hpp>
#include <vkjr2/sim/zernike.hpp>

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <string>

namespace vkjr2::sim {
namespace {

// Largest radial order any function here accepts: far beyond what a
// simulation uses (36 modes = order 7) but still accurate by the recurrence.
constexpr int kMaxOrder = 100;

void check_grid(const PupilGrid& grid, const char* op) {
  if (grid.size <= 0 || grid.size > 16384)
    throw InvalidArgument(op, "PupilGrid::size is " + std::to_string(grid.size),
                          "use a size in 1..16384");
  if (!(grid.diameter_px > 0) || !std::isfinite(grid.diameter_px))
    throw InvalidArgument(op, "PupilGrid::diameter_px must be > 0",
                          "give the pupil diameter in samples, ≤ size");
}

std::size_t cell(int n, int width, int m) {
  return static_cast<std::size_t>(n) * static_cast<std::size_t>(width) +
         static_cast<std::size_t>(m);
}

// All R_n^m(ρ) for n ≤ n_max into table[n·(n_max+2) + m] (m ≤ n + 1, zero
// where n − m is odd or m > n).
void radial_table(int n_max, double rho, std::vector<double>& table) {
  const int w = n_max + 2;
  table.assign(cell(n_max + 1, w, 0), 0.0);
  auto at = [&](int n, int m) -> double& { return table[cell(n, w, m)]; };
  at(0, 0) = 1;
  for (int n = 1; n <= n_max; ++n) {
    for (int m = n % 2; m <= n; m += 2) {
      const double left = at(n - 1, m == 0 ? 1 : m - 1);
      const double right = m + 1 <= n - 1 ? at(n - 1, m + 1) : 0.0;
      const double below = n >= 2 && m <= n - 2 ? at(n - 2, m) : 0.0;
      at(n, m) = rho * (left + right) - below;
    }
  }
}

double normalization(const ZernikeIndex& z) {
  return std::sqrt((z.m == 0 ? 1.0 : 2.0) * (z.n + 1));
}

}  // namespace

int noll_count_through_order(int n) { return (n + 1) * (n + 2) / 2; }

ZernikeIndex noll_index(int j) {
  if (j < 1 || j > noll_count_through_order(kMaxOrder))
    throw InvalidArgument("sim::noll_index",
                          "Noll index j = " + std::to_string(j) + " is out of range",
                          "Noll indices start at 1 (piston); 2, 3 are the tilts");
  int n = 0;
  while (noll_count_through_order(n) < j) ++n;
  const int k = j - noll_count_through_order(n - 1) - 1;  // position within the order
  ZernikeIndex z;
  z.n = n;
  z.m = n % 2 == 0 ? 2 * ((k + 1) / 2) : 2 * (k / 2) + 1;
  z.sine = z.m != 0 && j % 2 == 1;  // Noll: even j ↔ cos, odd j ↔ sin
  return z;
}

int noll_j(int n, int m, bool sine) {
  if (n < 0 || m < 0 || m > n || (n - m) % 2 != 0 || n > kMaxOrder)
    throw InvalidArgument(
        "sim::noll_j",
        "(n, m) = (" + std::to_string(n) + ", " + std::to_string(m) + ") is not a Zernike pair",
        "need 0 ≤ m ≤ n with n − m even");
  if (m == 0 && sine)
    throw InvalidArgument("sim::noll_j", "m = 0 has no sine mode", "pass sine = false for m = 0");
  const int first = noll_count_through_order(n - 1) + 1;
  for (int j = first; j <= noll_count_through_order(n); ++j) {
    const ZernikeIndex z = noll_index(j);
    if (z.m == m && z.sine == sine) return j;
  }
  return 0;  // unreachable: every valid pair has an index
}

double zernike_radial(int n, int m, double rho) {
  if (m < 0 || m > n || (n - m) % 2 != 0) return 0.0;
  if (n > kMaxOrder)
    throw InvalidArgument("sim::zernike_radial", "order n = " + std::to_string(n) + " is too high",
                          "use n ≤ " + std::to_string(kMaxOrder));
  std::vector<double> table;
  radial_table(n, rho, table);
  return table[cell(n, n + 2, m)];
}

double zernike(int j, double rho, double theta) {
  const ZernikeIndex z = noll_index(j);
  const double r = normalization(z) * zernike_radial(z.n, z.m, rho);
  if (z.m == 0) return r;
  return r * (z.sine ? std::sin(z.m * theta) : std::cos(z.m * theta));
}

double zernike_xy(int j, double x, double y) {
  return zernike(j, std::hypot(x, y), std::atan2(y, x));
}

std::vector<double> pupil_mask(const PupilGrid& grid) {
  check_grid(grid, "sim::pupil_mask");
  const int s = grid.size;
  const double c = (s - 1) / 2.0;
  const double scale = 2.0 / grid.diameter_px;
  std::vector<double> mask(static_cast<std::size_t>(s) * s, 0.0);
  for (int r = 0; r < s; ++r)
    for (int col = 0; col < s; ++col) {
      const double x = (col - c) * scale;
      const double y = (r - c) * scale;
      if (x * x + y * y <= 1.0) mask[static_cast<std::size_t>(r) * s + col] = 1.0;
    }
  return mask;
}

std::vector<double> zernike_modes(int first_j, int last_j, const PupilGrid& grid) {
  check_grid(grid, "sim::zernike_modes");
  if (first_j < 1 || last_j < first_j)
    throw InvalidArgument("sim::zernike_modes",
                          "mode range " + std::to_string(first_j) + ".." + std::to_string(last_j) +
                              " is empty or starts below 1",
                          "pass 1 ≤ first_j ≤ last_j");
  const int count = last_j - first_j + 1;
  std::vector<ZernikeIndex> idx;
  int n_max = 0;
  for (int j = first_j; j <= last_j; ++j) {
    idx.push_back(noll_index(j));
    n_max = std::max(n_max, idx.back().n);
  }
  const int s = grid.size;
  const std::size_t plane = static_cast<std::size_t>(s) * s;
  std::vector<double> out(plane * count, 0.0);
  const double c = (s - 1) / 2.0;
  const double scale = 2.0 / grid.diameter_px;
  std::vector<double> table;
  std::vector<double> cos_m(static_cast<std::size_t>(n_max + 1));
  std::vector<double> sin_m(static_cast<std::size_t>(n_max + 1));
  const int w = n_max + 2;
  for (int r = 0; r < s; ++r)
    for (int col = 0; col < s; ++col) {
      const double x = (col - c) * scale;
      const double y = (r - c) * scale;
      const double rho2 = x * x + y * y;
      if (rho2 > 1.0) continue;
      const double rho = std::sqrt(rho2);
      radial_table(n_max, rho, table);
      // cos(mθ), sin(mθ) by the angle-addition recurrence from cosθ = x/ρ.
      const double ct = rho > 0 ? x / rho : 1.0;
      const double st = rho > 0 ? y / rho : 0.0;
      cos_m[0] = 1;
      sin_m[0] = 0;
      for (int m = 1; m <= n_max; ++m) {
        cos_m[static_cast<std::size_t>(m)] = cos_m[static_cast<std::size_t>(m - 1)] * ct -
                                             sin_m[static_cast<std::size_t>(m - 1)] * st;
        sin_m[static_cast<std::size_t>(m)] = sin_m[static_cast<std::size_t>(m - 1)] * ct +
                                             cos_m[static_cast<std::size_t>(m - 1)] * st;
      }
      const std::size_t pix = static_cast<std::size_t>(r) * s + col;
      for (int k = 0; k < count; ++k) {
        const ZernikeIndex& z = idx[static_cast<std::size_t>(k)];
        double v = normalization(z) * table[cell(z.n, w, z.m)];
        if (z.m != 0)
          v *= z.sine ? sin_m[static_cast<std::size_t>(z.m)] : cos_m[static_cast<std::size_t>(z.m)];
        out[plane * k + pix] = v;
      }
    }
  return out;
}

void zernike_phase(std::span<const double> coeffs, int first_j, const PupilGrid& grid,
                   std::span<double> phase) {
  check_grid(grid, "sim::zernike_phase");
  const std::size_t plane = static_cast<std::size_t>(grid.size) * grid.size;
  if (phase.size() != plane)
    throw InvalidArgument("sim::zernike_phase",
                          "phase has " + std::to_string(phase.size()) + " values for a " +
                              std::to_string(grid.size) + "² grid",
                          "pass a buffer of size² values");
  if (coeffs.empty()) {
    std::fill(phase.begin(), phase.end(), 0.0);
    return;
  }
  for (std::size_t k = 0; k < coeffs.size(); ++k)
    if (!std::isfinite(coeffs[k]))
      throw InvalidArgument("sim::zernike_phase",
                            "coefficient " + std::to_string(k) + " (Z" +
                                std::to_string(first_j + static_cast<int>(k)) + ") is not finite",
                            "check the coefficient source for NaN/inf");
  const auto modes = zernike_modes(first_j, first_j + static_cast<int>(coeffs.size()) - 1, grid);
  std::fill(phase.begin(), phase.end(), 0.0);
  for (std::size_t k = 0; k < coeffs.size(); ++k) {
    const double a = coeffs[k];
    const double* mode = modes.data() + plane * k;
    for (std::size_t i = 0; i < plane; ++i) phase[i] += a * mode[i];
  }
}

}  // namespace vkjr2::sim
