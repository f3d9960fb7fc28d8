// Test support: devices with the Khronos validation layer on, where any
// validation message fails the running test.
#pragma once

#include <vkjr2/runtime/device.hpp>

#include <cstdint>
#include <random>
#include <vector>

namespace vkjr2::test {

// Options for every Device a test creates: validation on (unless
// VKJR2_VALIDATION=0), messages turned into test failures.
DeviceOptions options();

// The device shared by the tests of one process.
Device& device();

// How tensors reach the device and how kernels bind them.
enum class DevicePath {
  mapped,          // the default: host-visible tensors, push descriptors where present
  staging,         // every upload and download through a staging buffer
  descriptor_pool  // descriptor sets from pools (no VK_KHR_push_descriptor)
};
const char* path_name(DevicePath path);
// The process's device for a path (mapped: device()), made on first use.
Device& device(DevicePath path);

// Destroys the shared devices; returns the number of validation messages seen
// outside any test (0 = clean).
std::size_t shutdown();

// Seeded random values in [lo, hi); the seed is printed on failure by callers
// through SCOPED_TRACE.
std::vector<float> random_floats(std::size_t n, std::uint32_t seed, float lo = -1.f,
                                 float hi = 1.f);

}  // namespace vkjr2::test
