#include <vkjr2/runtime/error.hpp>
#include <vkjr2/sim/host_fft.hpp>

#include <fftw3.h>

#include <array>
#include <cmath>
#include <cstring>
#include <map>
#include <memory>
#include <mutex>
#include <string>
#include <tuple>

namespace vkjr2::sim {
namespace {

constexpr const char* kOp = "sim::fft2_fftw";

struct PlanDeleter {
  void operator()(fftwf_plan_s* plan) const noexcept { fftwf_destroy_plan(plan); }
};
struct BufferDeleter {
  void operator()(fftwf_complex* p) const noexcept { fftwf_free(p); }
};
using PlanPtr = std::unique_ptr<fftwf_plan_s, PlanDeleter>;
using BufferPtr = std::unique_ptr<fftwf_complex[], BufferDeleter>;

// The plans of this process, one per (B, H, W, sign), in place. FFTW_MEASURE
// overwrites the array it plans on, so plans are made on scratch and run
// with fftwf_execute_dft (thread-safe) on the caller's data, copied through
// an aligned buffer when the data's alignment differs from the scratch's
// (the plan's SIMD codelets assume it).
class PlanCache {
 public:
  fftwf_plan_s* get(int batch, int h, int w, int sign) {
    const std::lock_guard lock(mutex_);
    auto& plan = plans_[{batch, h, w, sign}];
    if (!plan) {
      const std::size_t count = std::size_t(batch) * std::size_t(h) * std::size_t(w);
      const BufferPtr scratch(fftwf_alloc_complex(count));
      const std::array<int, 2> dims{h, w};
      const int dist = h * w;
      plan.reset(fftwf_plan_many_dft(2, dims.data(), batch, scratch.get(), nullptr, 1, dist,
                                     scratch.get(), nullptr, 1, dist, sign, FFTW_MEASURE));
      if (!plan) {
        throw InvalidArgument(kOp, "FFTW could not plan [" + std::to_string(batch) + ", " +
                                       std::to_string(h) + ", " + std::to_string(w) + "]");
      }
    }
    return plan.get();
  }

 private:
  std::mutex mutex_;
  std::map<std::tuple<int, int, int, int>, PlanPtr> plans_;
};

PlanCache& plan_cache() {
  static PlanCache cache;  // FFTW's planner and wisdom are process-wide already
  return cache;
}

}  // namespace

const char* fft_backend_name(FftBackend backend) noexcept {
  return backend == FftBackend::fftw ? "fftw" : "device";
}

void fft2_fftw(const Shape& shape, std::span<float> data, bool inverse, kernels::FftNorm norm) {
  if (shape.rank() != 3 || shape[0] < 1 || shape[1] < 1 || shape[2] < 1 ||
      shape[1] * shape[2] > std::int64_t(1) << 30 || shape.numel() > std::int64_t(1) << 31) {
    throw InvalidArgument(kOp, "shape must be {B, H, W}, every axis ≥ 1, got " + shape.str(),
                          "pass the batch, height and width of the complex data");
  }
  const std::size_t count = std::size_t(shape.numel());
  if (data.size() != 2 * count) {
    throw InvalidArgument(kOp,
                          "data holds " + std::to_string(data.size()) + " floats, shape " +
                              shape.str() + " needs " + std::to_string(2 * count),
                          "pass complex [B, H, W, 2] data");
  }
  fftwf_plan_s* plan = plan_cache().get(int(shape[0]), int(shape[1]), int(shape[2]),
                                        inverse ? FFTW_BACKWARD : FFTW_FORWARD);
  // fftwf_complex is float[2]: the interleaved layout, by FFTW's guarantee.
  auto* z = reinterpret_cast<fftwf_complex*>(data.data());
  if (fftwf_alignment_of(data.data()) == 0) {
    fftwf_execute_dft(plan, z, z);
  } else {
    const BufferPtr aligned(fftwf_alloc_complex(count));
    std::memcpy(aligned.get(), data.data(), data.size_bytes());
    fftwf_execute_dft(plan, aligned.get(), aligned.get());
    std::memcpy(data.data(), aligned.get(), data.size_bytes());
  }
  const double n = double(shape[1]) * double(shape[2]);
  double scale = 1;
  if (norm == kernels::FftNorm::ortho) scale = 1 / std::sqrt(n);
  if (norm == kernels::FftNorm::backward && inverse) scale = 1 / n;
  if (scale != 1) {
    const auto s = static_cast<float>(scale);
    for (float& v : data) v *= s;
  }
}

void fft2_host(FftBackend backend, const Device& device, const Shape& shape,
               std::vector<float>& data, bool inverse, kernels::FftNorm norm) {
  if (backend == FftBackend::fftw) {
    fft2_fftw(shape, data, inverse, norm);
  } else {
    kernels::fft2_host(device, shape, data, inverse, norm);
  }
}

}  // namespace vkjr2::sim
