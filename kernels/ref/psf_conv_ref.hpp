// Plain C++ reference of kernels/psf_conv (tests only).
#pragma once

#include <vector>

namespace vkjr2::ref {

struct PsfConvDims {
  int n, c, k, h, w, s;
};

// y and norm as defined in kernels/psf_conv.hpp; straightforward loops in
// double, u_k = β_k ⊙ x convolved tap by tap.
void psf_conv(const PsfConvDims& d, const std::vector<float>& x, const std::vector<float>& beta,
              const std::vector<float>& psi, bool normalize, std::vector<float>& y,
              std::vector<float>& norm);

}  // namespace vkjr2::ref
