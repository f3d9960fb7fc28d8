// Plain C++ reference of kernels/conv2d (tests and benchmarks only):
// accumulates in double, same layouts and semantics as kernels/conv2d.hpp.
#pragma once

#include <vkjr2/kernels/conv2d.hpp>

#include <cstdint>
#include <span>
#include <vector>

namespace vkjr2::ref {

// x [n, cin, h, w], weight [cout, cin/groups, kh, kw].
struct Conv2dDims {
  std::int64_t n = 1, cin = 1, h = 1, w = 1, cout = 1, kh = 1, kw = 1;
};

// Output height and width for dims and params (no validation beyond the formula).
std::int64_t conv2d_out_h(const Conv2dDims& d, const kernels::Conv2dParams& p);
std::int64_t conv2d_out_w(const Conv2dDims& d, const kernels::Conv2dParams& p);

// y = act(conv(x, w) + bias + residual) (conv(relu(x), w) with p.relu_input);
// bias may be empty; residual [n, cres, hout, wout] (cres <= cout; channels
// past it get none) may be empty.
std::vector<float> conv2d(std::span<const float> x, std::span<const float> w,
                          std::span<const float> bias, const Conv2dDims& d,
                          const kernels::Conv2dParams& p, std::span<const float> residual = {},
                          std::int64_t cres = 0);
// dx for dy (no activation).
std::vector<float> conv2d_backward_data(std::span<const float> dy, std::span<const float> w,
                                        const Conv2dDims& d, const kernels::Conv2dParams& p);
// dw (and dbias = Σ dy per channel) for x and dy (no activation).
std::vector<float> conv2d_backward_weight(std::span<const float> x, std::span<const float> dy,
                                          const Conv2dDims& d, const kernels::Conv2dParams& p);
std::vector<float> conv2d_backward_bias(std::span<const float> dy, const Conv2dDims& d,
                                        const kernels::Conv2dParams& p);

}  // namespace vkjr2::ref
