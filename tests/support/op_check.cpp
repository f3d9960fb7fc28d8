#include "support/op_check.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <cstring>
#include <sstream>

#include "support/test_device.hpp"

namespace vkjr2::test {
namespace {

bool close(float got, float want, double bound) {
  if (std::isnan(want) || std::isnan(got)) return std::isnan(want) && std::isnan(got);
  if (std::isinf(want) || std::isinf(got)) return got == want;
  return std::fabs(double(got) - double(want)) <= bound;
}

std::vector<std::uint32_t> bits_of(std::span<const float> v) {
  std::vector<std::uint32_t> b(v.size());
  if (!v.empty()) std::memcpy(b.data(), v.data(), v.size_bytes());
  return b;
}

// Each case's seed: distinct per case, and the same on every path.
std::uint32_t case_seed(std::uint32_t seed, int index) {
  return seed * 2654435761u + std::uint32_t(index) * 40503u + 1u;
}

int failure_count() {
  const ::testing::TestResult* r =
      ::testing::UnitTest::GetInstance()->current_test_info()->result();
  int n = 0;
  for (int i = 0; i < r->total_part_count(); ++i) n += r->GetTestPartResult(i).failed() ? 1 : 0;
  return n;
}

}  // namespace

OpCase::OpCase(Device& device_, DevicePath path_, int index_, std::uint32_t seed_)
    : device(device_), path(path_), index(index_), seed(seed_), rng_(seed_) {}

int OpCase::uniform(int lo, int hi) { return std::uniform_int_distribution<int>(lo, hi)(rng_); }

std::vector<float> OpCase::floats(std::int64_t n, float lo, float hi) {
  std::uniform_real_distribution<float> dist(lo, hi);
  std::vector<float> v(std::size_t(std::max<std::int64_t>(n, 0)));
  for (float& x : v) x = dist(rng_);
  return v;
}

Shape OpCase::nchw(int max_n, int max_c, int max_h, int max_w) {
  const int n = uniform(1, max_n), c = uniform(1, max_c), h = uniform(1, max_h);
  return {n, c, h, uniform(1, max_w)};
}

Tensor OpCase::tensor(const Shape& shape, std::span<const float> values) const {
  return Tensor::from(device, shape, values);
}

Tensor OpCase::empty(const Shape& shape, DType dtype) const {
  return Tensor::empty(device, shape, dtype);
}

std::string OpCase::label(const std::string& name) const {
  return what_.empty() ? name : name + " (" + what_ + ")";
}

void OpCase::expect(const std::string& name, const Tensor& got, const std::vector<float>& want,
                    Tol tol) {
  expect(name, got.download(), want, tol);
}

void OpCase::expect(const std::string& name, const std::vector<float>& got,
                    const std::vector<float>& want, Tol tol) {
  expect_all_close(label(name), got, want, tol);
  outputs_.push_back({name, bits_of(got)});
}

void OpCase::expect(const std::string& name, const Tensor& got, const std::vector<float>& want,
                    std::span<const double> bound) {
  const std::vector<float> g = got.download();
  expect_all_close(label(name), g, want, bound);
  outputs_.push_back({name, bits_of(g)});
}

void OpCase::expect_rel_l2(const std::string& name, const std::vector<float>& got,
                           std::span<const double> want, double tol) {
  if (got.size() != want.size()) {
    ADD_FAILURE() << label(name) << ": " << got.size() << " values, the reference has "
                  << want.size();
    return;
  }
  EXPECT_LE(rel_l2(got, want), tol) << label(name) << ": relative L2 error";
  outputs_.push_back({name, bits_of(got)});
}

void OpCase::expect_equal(const std::string& name, const Tensor& got,
                          const std::vector<std::int32_t>& want) {
  std::vector<std::int32_t> v(std::size_t(got.numel()));
  got.download_bytes(v.data(), v.size() * sizeof(std::int32_t));
  EXPECT_EQ(v, want) << label(name);
  std::vector<std::uint32_t> b(v.size());
  if (!v.empty()) std::memcpy(b.data(), v.data(), v.size() * sizeof(std::int32_t));
  outputs_.push_back({name, std::move(b)});
}

double rel_l2(std::span<const float> got, std::span<const double> want) {
  double num = 0, den = 0;
  for (std::size_t i = 0; i < got.size(); ++i) {
    const double d = double(got[i]) - want[i];
    num += d * d;
    den += want[i] * want[i];
  }
  return std::sqrt(num / std::max(den, 1e-300));
}

Tol peak_relative(std::span<const float> want, double rtol) {
  double scale = 0;
  for (float v : want) scale = std::max(scale, double(std::fabs(v)));
  return {rtol, rtol * (1e-2 * scale + 1e-37)};
}

namespace {

// One failure per output: the first and the worst element and the count.
template <class Bound>
void expect_within(std::string_view name, std::span<const float> got, std::span<const float> want,
                   Bound bound, const std::string& rule) {
  if (got.size() != want.size()) {
    ADD_FAILURE() << name << ": " << got.size() << " values, the reference has " << want.size();
    return;
  }
  std::size_t misses = 0, first = 0, worst = 0;
  double worst_excess = -1;
  for (std::size_t i = 0; i < got.size(); ++i) {
    const double b = bound(i);
    if (close(got[i], want[i], b)) continue;
    if (misses++ == 0) first = i;
    const double err = std::fabs(double(got[i]) - double(want[i]));
    const double excess = std::isfinite(err) ? err / b : INFINITY;
    if (excess > worst_excess) worst_excess = excess, worst = i;
  }
  if (misses == 0) return;
  ADD_FAILURE() << name << ": " << misses << " of " << got.size() << " values off the reference ("
                << rule << "); first at " << first << ": " << got[first] << " vs " << want[first]
                << "; worst at " << worst << ": " << got[worst] << " vs " << want[worst]
                << " (bound " << bound(worst) << ")";
}

}  // namespace

void expect_all_close(std::string_view name, std::span<const float> got,
                      std::span<const float> want, Tol tol) {
  std::ostringstream rule;
  rule << "rtol " << tol.rtol << ", atol " << tol.atol;
  expect_within(
      name, got, want,
      [&](std::size_t i) { return tol.atol + tol.rtol * std::fabs(double(want[i])); }, rule.str());
}

void expect_all_close(std::string_view name, std::span<const float> got,
                      std::span<const float> want, std::span<const double> bound) {
  if (bound.size() != want.size()) {
    ADD_FAILURE() << name << ": " << bound.size() << " bounds for " << want.size() << " values";
    return;
  }
  expect_within(
      name, got, want, [&](std::size_t i) { return bound[i]; }, "per-element bound");
}

void check_op(std::string_view op, const OpCheck& options,
              const std::function<void(OpCase&)>& body) {
  const char* paths = std::getenv("VKJR2_TEST_DEVICE_PATHS");
  const bool mapped_only = paths != nullptr && std::string_view(paths) == "mapped";
  for (int i = 0; i < options.cases; ++i) {
    const std::uint32_t seed = case_seed(options.seed, i);
    std::vector<OpCase::Output> first;
    std::string what;
    const bool every_path = !mapped_only && i < options.cases_on_every_path;
    for (DevicePath path : {DevicePath::mapped, DevicePath::staging, DevicePath::descriptor_pool}) {
      if (path != DevicePath::mapped && !every_path) break;
      std::ostringstream trace;
      trace << op << ", case " << i << " (seed " << seed << "), " << path_name(path) << " path";
      SCOPED_TRACE(trace.str());
      OpCase c(device(path), path, i, seed);
      const int failures_before = failure_count();
      body(c);
      if (failure_count() > failures_before) {
        // One case's failures are enough to read; the rest would repeat them.
        ADD_FAILURE() << op << " stopped at case " << i << " (" << c.description() << ")";
        return;
      }
      if (path == DevicePath::mapped) {
        first = c.outputs();
        what = c.description();
        continue;
      }
      // The same draws on another path: the same outputs, bit for bit.
      if (c.outputs().size() != first.size()) {
        ADD_FAILURE() << c.outputs().size() << " outputs, the mapped path had " << first.size();
        continue;
      }
      for (std::size_t k = 0; k < first.size(); ++k) {
        EXPECT_EQ(c.outputs()[k].name, first[k].name);
        EXPECT_TRUE(c.outputs()[k].bits == first[k].bits)
            << first[k].name << " differs from the mapped path's (" << what << ")";
      }
    }
  }
}

}  // namespace vkjr2::test
