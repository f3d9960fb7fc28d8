#include <vkjr2/runtime/device.hpp>
#include <vkjr2/runtime/device_traits.hpp>
#include <vkjr2/runtime/error.hpp>
#include <vkjr2/runtime/kernel.hpp>

#include <gtest/gtest.h>

#include <cstdlib>
#include <string>

#include "support/test_device.hpp"

namespace vkjr2 {
namespace {

bool is_llvmpipe(const DeviceInfo& info) {
  return info.driver_id == VK_DRIVER_ID_MESA_LLVMPIPE ||
         info.name.find("llvmpipe") != std::string::npos;
}

TEST(DeviceTraits, ChosenByTheDriverOrForced) {
  const Device& device = test::device();
  const char* forced = std::getenv("VKJR2_DEVICE_TRAITS");
  const std::string want =
      forced != nullptr ? std::string(forced) : (is_llvmpipe(device.info()) ? "lavapipe" : "gpu");
  EXPECT_EQ(device.traits().profile, want);
  EXPECT_EQ(device.traits().measured, want == "lavapipe");

  // An explicit profile wins over the device and the environment.
  EXPECT_EQ(device_traits_for(device.info(), "gpu").profile, "gpu");
  EXPECT_EQ(device_traits_for(device.info(), "lavapipe").profile, "lavapipe");

  DeviceInfo gpu;
  gpu.name = "NVIDIA H100";
  gpu.type = VK_PHYSICAL_DEVICE_TYPE_DISCRETE_GPU;
  gpu.driver_id = VK_DRIVER_ID_NVIDIA_PROPRIETARY;
  DeviceInfo cpu;
  cpu.name = "llvmpipe (LLVM 15.0.6, 256 bits)";
  cpu.type = VK_PHYSICAL_DEVICE_TYPE_CPU;
  if (forced == nullptr) {
    EXPECT_EQ(device_traits_for(gpu).profile, "gpu");
    EXPECT_EQ(device_traits_for(cpu).profile, "lavapipe");  // by name when the driver id is unset
  }
}

TEST(DeviceTraits, ProfilesDifferWhereTheyShould) {
  const DeviceTraits lvp = lavapipe_traits();
  const DeviceTraits gpu = gpu_traits();
  // lavapipe runs a workgroup per CPU thread: small dispatches are split.
  EXPECT_GT(lvp.min_workgroups, 1u);
  EXPECT_EQ(gpu.min_workgroups, 1u);
  EXPECT_LE(gpu.conv_max_tile_accumulators, lvp.conv_max_tile_accumulators);
  EXPECT_GE(lvp.fft_max_log2_radix, 1u);
  EXPECT_LE(lvp.fft_max_log2_radix, 5u);
  EXPECT_GE(gpu.fft_max_log2_radix, 1u);
  EXPECT_LE(gpu.fft_max_log2_radix, 5u);
  EXPECT_GT(lvp.psf_direct_seconds_per_tap, 0);
  EXPECT_GT(gpu.psf_fft_seconds_per_point_log, 0);
}

TEST(DeviceTraits, GroupLanesFollowTheProfile) {
  // 100 invocations: 4 workgroups wanted → 16 lanes (100 < 32·4); a GPU keeps 64.
  EXPECT_EQ(group_lanes(100, lavapipe_traits().min_workgroups), 16u);
  EXPECT_EQ(group_lanes(100, gpu_traits().min_workgroups), 64u);
  EXPECT_EQ(group_lanes(10, lavapipe_traits().min_workgroups), 8u);  // never below 8
  EXPECT_EQ(group_lanes(1 << 20, lavapipe_traits().min_workgroups), 64u);
}

TEST(DeviceTraits, UnknownProfileIsAClearError) {
  try {
    (void)device_traits_for(test::device().info(), "fast");
    ADD_FAILURE() << "no error";
  } catch (const InvalidArgument& e) {
    const std::string what = e.what();
    EXPECT_NE(what.find("'fast'"), std::string::npos) << what;
    EXPECT_NE(what.find("lavapipe"), std::string::npos) << what;
    EXPECT_NE(what.find("gpu"), std::string::npos) << what;
  }
}

}  // namespace
}  // namespace vkjr2
