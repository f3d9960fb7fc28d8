// Gauss–Legendre quadrature for the simulator's host-side integrals.
#pragma once

#include <vector>

namespace vkjr2::sim {

// n-point Gauss–Legendre nodes and weights on [−1, 1], by Newton's method on
// P_n (computed, not typed in): exact for polynomials of degree ≤ 2n − 1.
struct GaussLegendre {
  explicit GaussLegendre(int n);
  std::vector<double> x, w;
};

}  // namespace vkjr2::sim
