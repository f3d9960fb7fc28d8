#include "support/test_device.hpp"

#include <gtest/gtest.h>

#include <atomic>
#include <cstdlib>
#include <iostream>
#include <memory>
#include <string>

namespace vkjr2::test {
namespace {

std::atomic<std::size_t> g_outside_messages{0};
std::unique_ptr<Device> g_device;
std::unique_ptr<Device> g_staging_device, g_pool_device;

void on_message(std::string_view message) {
  if (::testing::UnitTest::GetInstance()->current_test_info() != nullptr) {
    ADD_FAILURE() << "Vulkan validation " << message;
  } else {
    std::cerr << "Vulkan validation (outside a test) " << message << "\n";
    ++g_outside_messages;
  }
}

}  // namespace

DeviceOptions options() {
  DeviceOptions o;
  const char* v = std::getenv("VKJR2_VALIDATION");
  o.validation = !(v != nullptr && std::string(v) == "0");
  o.on_validation_message = on_message;
  return o;
}

Device& device() {
  if (!g_device) g_device = std::make_unique<Device>(options());
  return *g_device;
}

const char* path_name(DevicePath path) {
  switch (path) {
    case DevicePath::mapped:
      return "mapped";
    case DevicePath::staging:
      return "staging";
    case DevicePath::descriptor_pool:
      return "descriptor-pool";
  }
  return "?";
}

Device& device(DevicePath path) {
  if (path == DevicePath::mapped) return device();
  auto& slot = path == DevicePath::staging ? g_staging_device : g_pool_device;
  if (!slot) {
    DeviceOptions o = options();
    o.force_staging = path == DevicePath::staging;
    o.push_descriptors = path != DevicePath::descriptor_pool;
    slot = std::make_unique<Device>(o);
  }
  return *slot;
}

std::size_t shutdown() {
  g_staging_device.reset();
  g_pool_device.reset();
  g_device.reset();
  return g_outside_messages.load();
}

std::vector<float> random_floats(std::size_t n, std::uint32_t seed, float lo, float hi) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<float> dist(lo, hi);
  std::vector<float> v(n);
  for (float& x : v) x = dist(rng);
  return v;
}

}  // namespace vkjr2::test
