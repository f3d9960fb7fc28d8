#include <vkjr2/runtime/error.hpp>
#include <vkjr2/sim/short_exposure.hpp>

#include <cmath>
#include <numbers>
#include <string>
#include <vector>

namespace vkjr2::sim {
namespace {

constexpr double kPi = std::numbers::pi;
// Points on the unit circle for the centroid's contour integrals.
constexpr int kContourPoints = 720;

struct Point {
  double x, y;
};

// Kolmogorov phase structure function for D/r0 = k at a separation s in
// units of the pupil radius: 6.88 (k s / 2)^(5/3).
double structure(double s, double k) {
  const double q = k * s / 2;
  return 6.88 * q * std::cbrt(q * q);
}

// Cell centres of a grid × grid raster over [−1, 1]² that lie in the unit disk.
std::vector<Point> disk_points(int grid) {
  std::vector<Point> p;
  const double h = 2.0 / grid;
  for (int i = 0; i < grid; ++i)
    for (int j = 0; j < grid; ++j) {
      const double x = -1 + (j + 0.5) * h, y = -1 + (i + 0.5) * h;
      if (x * x + y * y <= 1) p.push_back({x, y});
    }
  return p;
}

// The removed tilt as a linear functional t = ∫ w(y) φ(y): its sample
// points and weights (Z-tilt: Z_2(y)/π over the disk; G-tilt: cos θ/π on
// the circle, by the divergence theorem). The phase gradient of the tilt is
// `gain` · t along x (Z-tilt: 2 a_2 per radius; G-tilt: g_x).
struct Functional {
  std::vector<Point> at;
  std::vector<double> weight;
  double gain = 1;
};

Functional tilt_functional(TiltRemoval removal, int grid) {
  Functional f;
  if (removal == TiltRemoval::zernike) {
    const double h = 2.0 / grid;
    f.at = disk_points(grid);
    for (const Point& p : f.at) f.weight.push_back(2 * p.x * h * h / kPi);
    f.gain = 2;
  } else {
    const double dt = 2 * kPi / kContourPoints;
    for (int i = 0; i < kContourPoints; ++i) {
      const double t = (i + 0.5) * dt;
      f.at.push_back({std::cos(t), std::sin(t)});
      f.weight.push_back(std::cos(t) * dt / kPi);
    }
    f.gain = 1;
  }
  return f;
}

// E[φ(x) t] = −½ Σ w(y) D(|x − y|) (the covariance's constant integrates out).
double phase_tilt_covariance(const Functional& f, Point x, double k) {
  double s = 0;
  for (std::size_t i = 0; i < f.at.size(); ++i)
    s += f.weight[i] * structure(std::hypot(x.x - f.at[i].x, x.y - f.at[i].y), k);
  return -0.5 * s;
}

// E[t²] = −½ ΣΣ w w' D(|y − y'|).
double tilt_variance(const Functional& f, double k) {
  double s = 0;
  for (std::size_t i = 0; i < f.at.size(); ++i)
    for (std::size_t j = 0; j < f.at.size(); ++j)
      s += f.weight[i] * f.weight[j] *
           structure(std::hypot(f.at[i].x - f.at[j].x, f.at[i].y - f.at[j].y), k);
  return -0.5 * s;
}

void check_grid(int grid, const char* op) {
  if (grid < 8 || grid > 1024)
    throw InvalidArgument(op, "grid " + std::to_string(grid) + " is outside 8..1024",
                          "use the default 96");
}

}  // namespace

double removed_tilt_variance(TiltRemoval removal, int grid) {
  const char* op = "sim::removed_tilt_variance";
  check_grid(grid, op);
  if (removal == TiltRemoval::none) return 0;
  const Functional f = tilt_functional(removal, grid);
  return f.gain * f.gain * tilt_variance(f, 1.0);
}

double atmospheric_otf(double r_over_d, double d_over_r0, TiltRemoval removal, int grid) {
  const char* op = "sim::atmospheric_otf";
  if (!(r_over_d > 0 && r_over_d < 1))
    throw InvalidArgument(op, "r/D = " + std::to_string(r_over_d) + " is outside (0, 1)");
  if (!(d_over_r0 > 0 && std::isfinite(d_over_r0)))
    throw InvalidArgument(op, "D/r0 = " + std::to_string(d_over_r0) + " is not positive");
  check_grid(grid, op);
  const double k = d_over_r0, r = 2 * r_over_d;  // r in pupil radii
  const double d_r = structure(r, k);
  if (removal == TiltRemoval::none) return std::exp(-0.5 * d_r);
  const Functional f = tilt_functional(removal, grid);
  // The tilt's phase difference over r: ΔT = gain · t · r.
  const double var_t = tilt_variance(f, k);
  const int n = grid;
  const double h = 2.0 / n;
  double sum = 0, area = 0;
  for (int i = 0; i < n; ++i)
    for (int j = 0; j < n; ++j) {
      const Point a{-1 + (j + 0.5) * h, -1 + (i + 0.5) * h}, b{a.x + r, a.y};
      if (a.x * a.x + a.y * a.y > 1 || b.x * b.x + b.y * b.y > 1) continue;
      const double cross =
          f.gain * r * (phase_tilt_covariance(f, b, k) - phase_tilt_covariance(f, a, k));
      const double d = d_r - 2 * cross + f.gain * f.gain * r * r * var_t;
      sum += std::exp(-0.5 * d);
      area += 1;
    }
  if (area == 0)
    throw InvalidArgument(op, "the grid is too coarse for r/D = " + std::to_string(r_over_d));
  return sum / area;
}

}  // namespace vkjr2::sim
