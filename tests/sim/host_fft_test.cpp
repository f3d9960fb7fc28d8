#include <vkjr2/kernels/fft.hpp>
#include <vkjr2/runtime/error.hpp>
#include <vkjr2/sim/host_fft.hpp>

#include <gtest/gtest.h>

#include <cmath>
#include <cstdint>
#include <vector>

#include "support/test_device.hpp"

namespace vkjr2::sim {
namespace {

// FFTW and the device FFT on the same data, every norm and direction, a
// mixed-radix shape. Both are float FFTs with ~1e-7 · log2 N relative rms
// error; 1e-5 of the largest output is a 20× margin.
TEST(HostFft, FftwMatchesTheDeviceFft) {
  const Shape shape{3, 12, 20};
  const std::uint32_t seed = 7;
  SCOPED_TRACE(seed);
  const std::vector<float> x = test::random_floats(std::size_t(shape.numel()) * 2, seed);
  for (const auto norm :
       {kernels::FftNorm::backward, kernels::FftNorm::none, kernels::FftNorm::ortho}) {
    for (const bool inverse : {false, true}) {
      SCOPED_TRACE(inverse ? "inverse" : "forward");
      std::vector<float> a = x, b = x;
      fft2_host(FftBackend::device, test::device(), shape, a, inverse, norm);
      fft2_host(FftBackend::fftw, test::device(), shape, b, inverse, norm);
      double peak = 0, diff = 0;
      for (std::size_t i = 0; i < a.size(); ++i) {
        peak = std::max(peak, double(std::abs(a[i])));
        diff = std::max(diff, double(std::abs(a[i] - b[i])));
      }
      EXPECT_LT(diff, 1e-5 * peak);
    }
  }
  // Data not aligned for FFTW's SIMD plans goes through a copy, same result.
  std::vector<float> padded(x.size() + 2, 0.f), direct = x;
  std::copy(x.begin(), x.end(), padded.begin() + 2);
  fft2_fftw(shape, std::span(padded).subspan(2), /*inverse=*/false);
  fft2_fftw(shape, direct, /*inverse=*/false);
  for (std::size_t i = 0; i < x.size(); ++i) ASSERT_EQ(padded[i + 2], direct[i]) << i;
}

TEST(HostFft, RejectsBadShapes) {
  std::vector<float> data(2 * 16);
  EXPECT_THROW(fft2_fftw(Shape{4, 4}, data, false), InvalidArgument);
  EXPECT_THROW(fft2_fftw(Shape{1, 4, 5}, data, false), InvalidArgument);
}

}  // namespace
}  // namespace vkjr2::sim
