// One call that checks a kernel against its C++ reference (the idea of
// ncnn's test_layer):
//
//   test::check_op("max_pool2d", {.seed = 501}, [](test::OpCase& c) {
//     const Shape xs{c.uniform(1, 3), c.uniform(1, 5), c.uniform(1, 40), c.uniform(1, 40)};
//     c.describe("x " + xs.str());
//     const auto xv = c.floats(xs.numel());
//     Tensor x = c.tensor(xs, xv), y = ...;
//     Stream s(c.device);  kernels::...(s, x, y);  s.run();
//     c.expect("y", y, ref::...(xv, ...));
//   });
//
// The body draws its shapes and values from the case's seeded generator, so
// every case is another random shape. Each case runs on the shared test
// device; the first `cases_on_every_path` cases run again on a device whose
// tensors go through staging buffers and on one that binds through
// descriptor pools instead of push descriptors. Every output must match its
// reference within the tolerance, and the same case must give bit-identical
// outputs on every path (the memory and binding paths change no arithmetic).
// The 16-lane subgroup and GPU-profile runs are ctest entries
// (tests/CMakeLists.txt): the lane count is fixed when the driver loads. They
// set VKJR2_TEST_DEVICE_PATHS=mapped, since the memory and binding paths do not
// depend on either and the main run has checked them (each extra device
// compiles its pipelines again, seconds per kernel family on lavapipe).
#pragma once

#include <vkjr2/runtime/device.hpp>
#include <vkjr2/runtime/tensor.hpp>

#include <cstdint>
#include <functional>
#include <random>
#include <span>
#include <string>
#include <string_view>
#include <vector>

#include "support/test_device.hpp"

namespace vkjr2::test {

// |got − want| ≤ atol + rtol·|want| for every element.
struct Tol {
  double rtol = 1e-5;
  double atol = 1e-6;
};
// Bit-for-bit equal (permutations, copies, max and fill values).
inline constexpr Tol kExact{0, 0};

// ‖got − want‖₂ / ‖want‖₂.
double rel_l2(std::span<const float> got, std::span<const double> want);

// rtol relative to each value plus 1e-2·rtol of the largest |want|: for
// outputs that are sums of interpolation taps, whose rounding follows the
// output's scale rather than each value's.
Tol peak_relative(std::span<const float> want, double rtol);

// One run of the op under test: its device, its seeded generator, and the
// outputs recorded against their references.
class OpCase {
 public:
  OpCase(Device& device, DevicePath path, int index, std::uint32_t seed);

  Device& device;
  const DevicePath path;
  const int index;           // 0, 1, ... within check_op
  const std::uint32_t seed;  // seeds rng()

  std::mt19937& rng() { return rng_; }
  int uniform(int lo, int hi);  // in [lo, hi]
  std::vector<float> floats(std::int64_t n, float lo = -1.f, float hi = 1.f);
  // [n, c, h, w] with each extent drawn in [1, max].
  Shape nchw(int max_n, int max_c, int max_h, int max_w);
  // edges[index] while edge shapes are left (the ones a kernel gets wrong:
  // one element, a partial workgroup, 1×1 images), then random().
  template <class Random>
  Shape edge_or(const std::vector<Shape>& edges, Random&& random) {
    return index < int(edges.size()) ? edges[std::size_t(index)] : random();
  }
  Tensor tensor(const Shape& shape, std::span<const float> values) const;
  Tensor empty(const Shape& shape, DType dtype = DType::f32) const;

  // What this case is (shapes, parameters), printed with any failure.
  void describe(std::string what) { what_ = std::move(what); }
  const std::string& description() const { return what_; }

  // Compares an output with its reference now; keeps its bits for the
  // comparison across paths.
  void expect(const std::string& name, const Tensor& got, const std::vector<float>& want,
              Tol tol = {});
  void expect(const std::string& name, const std::vector<float>& got,
              const std::vector<float>& want, Tol tol = {});
  // |got[i] − want[i]| ≤ bound[i]: for outputs whose rounding follows
  // another quantity (a dot product's Σ|x||w|), not |want|.
  void expect(const std::string& name, const Tensor& got, const std::vector<float>& want,
              std::span<const double> bound);
  // ‖got − want‖₂ ≤ tol·‖want‖₂: for transforms compared with a peer library
  // (an FFT against FFTW), whose rounding spreads over the whole output.
  void expect_rel_l2(const std::string& name, const std::vector<float>& got,
                     std::span<const double> want, double tol);
  // Integer outputs (indices, labels): equal, element by element.
  void expect_equal(const std::string& name, const Tensor& got,
                    const std::vector<std::int32_t>& want);

  struct Output {
    std::string name;
    std::vector<std::uint32_t> bits;
  };
  const std::vector<Output>& outputs() const { return outputs_; }

 private:
  // name, with the case's description when there is one.
  std::string label(const std::string& name) const;

  std::mt19937 rng_;
  std::string what_;
  std::vector<Output> outputs_;
};

struct OpCheck {
  std::uint32_t seed = 1;
  int cases = 8;                // random shapes on the shared device
  int cases_on_every_path = 1;  // the first ones also on the staging and descriptor-pool paths
};

// Runs `body` for each case and path (see the top of this file). Stops at the
// first case that fails.
void check_op(std::string_view op, const OpCheck& options,
              const std::function<void(OpCase&)>& body);

// The element-wise comparison behind OpCase::expect, for checks outside
// check_op: one failure per output, naming the first and the worst element
// and the number of misses.
void expect_all_close(std::string_view name, std::span<const float> got,
                      std::span<const float> want, Tol tol = {});
void expect_all_close(std::string_view name, std::span<const float> got,
                      std::span<const float> want, std::span<const double> bound);

}  // namespace vkjr2::test
