// 2-D c2c FFTs of host data on either backend: the device (kernels/fft.hpp)
// or the CPU with FFTW (libfftw3f, single precision). Both take the same
// layout, [B, H, W, 2] (re, im) interleaved, and the conventions and
// FftNorm scalings of kernels/fft.hpp, so results agree to float rounding.
// The FFTW path never touches a device: the wave-optics reference on it is
// the fastest wave optics this machine's CPU runs, the peer `vkjr2 bench
// sim` measures the fast simulator against.
#pragma once

#include <vkjr2/kernels/fft.hpp>
#include <vkjr2/runtime/device.hpp>

#include <cstddef>
#include <cstdint>
#include <new>
#include <span>
#include <vector>

namespace vkjr2::sim {

enum class FftBackend : std::uint8_t {
  device,  // kernels::FftPlan on the Device (and the reference's shaders)
  fftw,    // FFTW on the CPU, one thread; everything else on the host
};

// "device" or "fftw".
const char* fft_backend_name(FftBackend backend) noexcept;

// In place on the CPU: data holds complex [B, H, W, 2] for shape {B, H, W}.
// Plans (FFTW_MEASURE, one thread) are made once per (B, H, W, direction)
// and kept for the process; FFTW's planner is process-wide state, so
// planning is serialized, execution is not. Throws InvalidArgument for a
// shape that is not {B, H, W} with every axis ≥ 1 or a size mismatch.
void fft2_fftw(const Shape& shape, std::span<float> data, bool inverse,
               kernels::FftNorm norm = kernels::FftNorm::backward);

// Float storage aligned as FFTW's SIMD plans want (64 bytes covers AVX-512):
// fft2_fftw runs on it in place, where other data goes through a copy.
template <class T>
struct FftwAllocator {
  using value_type = T;
  FftwAllocator() = default;
  template <class U>
  explicit FftwAllocator(const FftwAllocator<U>& /*other*/) noexcept {}
  T* allocate(std::size_t n) {
    return static_cast<T*>(::operator new (n * sizeof(T), std::align_val_t{64}));
  }
  void deallocate(T* p, std::size_t /*n*/) noexcept { ::operator delete (p, std::align_val_t{64}); }
  bool operator==(const FftwAllocator& /*other*/) const noexcept { return true; }
};
using FftwFloats = std::vector<float, FftwAllocator<float>>;

// kernels::fft2_host on FftBackend::device, fft2_fftw on FftBackend::fftw
// (device unused).
void fft2_host(FftBackend backend, const Device& device, const Shape& shape,
               std::vector<float>& data, bool inverse,
               kernels::FftNorm norm = kernels::FftNorm::backward);

}  // namespace vkjr2::sim
