#include <vkjr2/kernels/basic.hpp>
#include <vkjr2/runtime/device.hpp>
#include <vkjr2/runtime/stream.hpp>

#include <gtest/gtest.h>

#include <cstdlib>
#include <cstring>
#include <string>

#include "support/host_vulkan.hpp"
#include "support/test_device.hpp"

namespace vkjr2 {
namespace {

// Sets an environment variable for one scope.
class ScopedEnv {
 public:
  ScopedEnv(const char* name, const char* value) : name_(name) {
    if (const char* old = std::getenv(name)) old_ = old;
    had_ = std::getenv(name) != nullptr;
    if (value) {
      setenv(name, value, 1);
    } else {
      unsetenv(name);
    }
  }
  ~ScopedEnv() {
    if (had_) {
      setenv(name_.c_str(), old_.c_str(), 1);
    } else {
      unsetenv(name_.c_str());
    }
  }

 private:
  std::string name_;
  std::string old_;
  bool had_ = false;
};

DeviceInfo fake(std::uint32_t index, const char* name, VkPhysicalDeviceType type) {
  DeviceInfo d;
  d.index = index;
  d.name = name;
  d.type = type;
  d.api_version = VK_API_VERSION_1_2;
  return d;
}

TEST(Device, ListsLavapipe) {
  const auto devices = list_devices();
  ASSERT_FALSE(devices.empty());
  bool found = false;
  for (const auto& d : devices) found = found || d.name.find("llvmpipe") != std::string::npos;
  EXPECT_TRUE(found) << "expected Mesa lavapipe among the devices";
}

TEST(Device, SharedTestDeviceHasValidationAndLimits) {
  Device& dev = test::device();
  EXPECT_TRUE(dev.validation_enabled() || std::getenv("VKJR2_VALIDATION") != nullptr);
  const DeviceInfo& info = dev.info();
  EXPECT_GT(info.subgroup_size, 0u);
  EXPECT_GE(info.max_storage_buffer_range, 1u << 27);
  EXPECT_GE(info.max_push_constant_bytes, 128u);
  EXPECT_FALSE(info.heaps.empty());
}

TEST(DeviceSelection, RanksDiscreteIntegratedVirtualCpu) {
  std::vector<DeviceInfo> devices = {
      fake(0, "llvmpipe", VK_PHYSICAL_DEVICE_TYPE_CPU),
      fake(1, "Virtio GPU", VK_PHYSICAL_DEVICE_TYPE_VIRTUAL_GPU),
      fake(2, "Intel UHD", VK_PHYSICAL_DEVICE_TYPE_INTEGRATED_GPU),
      fake(3, "NVIDIA H100", VK_PHYSICAL_DEVICE_TYPE_DISCRETE_GPU),
  };
  EXPECT_EQ(select_device(devices, ""), 3u);
  devices.pop_back();
  EXPECT_EQ(select_device(devices, ""), 2u);
  devices.pop_back();
  EXPECT_EQ(select_device(devices, ""), 1u);
  devices.pop_back();
  EXPECT_EQ(select_device(devices, ""), 0u);
}

TEST(DeviceSelection, ByIndexAndNameSubstring) {
  const std::vector<DeviceInfo> devices = {
      fake(0, "llvmpipe (LLVM 15)", VK_PHYSICAL_DEVICE_TYPE_CPU),
      fake(1, "NVIDIA H100", VK_PHYSICAL_DEVICE_TYPE_DISCRETE_GPU),
  };
  EXPECT_EQ(select_device(devices, "0"), 0u);
  EXPECT_EQ(select_device(devices, "1"), 1u);
  EXPECT_EQ(select_device(devices, "LLVMpipe"), 0u);  // case-insensitive
  EXPECT_EQ(select_device(devices, "h100"), 1u);
  try {
    select_device(devices, "7");
    FAIL() << "index out of range accepted";
  } catch (const InvalidArgument& e) {
    EXPECT_NE(std::string(e.what()).find("out of range"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("NVIDIA H100"), std::string::npos) << e.what();
  }
  EXPECT_THROW(select_device(devices, "radeon"), InvalidArgument);
}

TEST(DeviceSelection, EnvironmentVariablePicksDevice) {
  {
    ScopedEnv env("VKJR2_DEVICE", "llvmpipe");
    Device dev(test::options());
    EXPECT_NE(dev.info().name.find("llvmpipe"), std::string::npos);
  }
  {
    ScopedEnv env("VKJR2_DEVICE", "0");
    Device dev(test::options());
    EXPECT_EQ(dev.info().index, 0u);
  }
  {
    ScopedEnv env("VKJR2_DEVICE", "no-such-gpu");
    try {
      Device dev(test::options());
      FAIL() << "unknown device name accepted";
    } catch (const InvalidArgument& e) {
      EXPECT_NE(std::string(e.what()).find("no-such-gpu"), std::string::npos) << e.what();
    }
  }
}

TEST(Device, NoDriverGivesInstallHint) {
  // An empty driver list is what a machine without a Vulkan driver looks like.
  ScopedEnv icd("VK_ICD_FILENAMES", "/nonexistent/vkjr2_no_driver.json");
  ScopedEnv drivers("VK_DRIVER_FILES", "/nonexistent/vkjr2_no_driver.json");
  DeviceOptions o = test::options();
  o.validation = false;
  try {
    Device dev(o);
    FAIL() << "a device was created without a driver";
  } catch (const NoDeviceError& e) {
    const std::string msg = e.what();
    EXPECT_NE(msg.find("mesa-vulkan-drivers"), std::string::npos) << msg;
    EXPECT_NE(msg.find("VK_ICD_FILENAMES"), std::string::npos) << msg;
  }
  EXPECT_THROW(list_devices(), NoDeviceError);
}

TEST(Device, ProfilingReportsKernelTimes) {
  DeviceOptions o = test::options();
  o.profile = true;
  Device dev(o);
  ASSERT_TRUE(dev.profiling_enabled());
  Stream s(dev);
  Tensor x = Tensor::from(dev, {1000}, test::random_floats(1000, 1));
  Tensor y = Tensor::from(dev, {1000}, test::random_floats(1000, 2));
  for (int i = 0; i < 3; ++i) kernels::axpy(s, 0.5f, x, y);
  s.run();
  const std::string report = dev.profile_report();
  EXPECT_NE(report.find("axpy"), std::string::npos) << report;
  EXPECT_NE(report.find('3'), std::string::npos) << report;
}

// --- adoption of a host application's Vulkan objects ----------------------

// The host application's own instance (validation + synchronization
// validation), device and queue: tests/support/host_vulkan.hpp.
using test::HostVulkan;

TEST(Device, AdoptsHostDeviceAndBuffersWithoutOwningThem) {
  HostVulkan host;
  ASSERT_NE(host.device, VK_NULL_HANDLE);

  // The host's own buffer, e.g. a decoded video frame.
  constexpr std::size_t n = 4099;
  VkBufferCreateInfo bi{VK_STRUCTURE_TYPE_BUFFER_CREATE_INFO};
  bi.size = n * sizeof(float);
  bi.usage = VK_BUFFER_USAGE_STORAGE_BUFFER_BIT | VK_BUFFER_USAGE_UNIFORM_TEXEL_BUFFER_BIT |
             VK_BUFFER_USAGE_TRANSFER_SRC_BIT | VK_BUFFER_USAGE_TRANSFER_DST_BIT;
  VkBuffer host_buffer = VK_NULL_HANDLE;
  ASSERT_EQ(vkCreateBuffer(host.device, &bi, nullptr, &host_buffer), VK_SUCCESS);
  VkMemoryRequirements req{};
  vkGetBufferMemoryRequirements(host.device, host_buffer, &req);
  VkMemoryAllocateInfo ai{VK_STRUCTURE_TYPE_MEMORY_ALLOCATE_INFO};
  ai.allocationSize = req.size;
  ai.memoryTypeIndex = static_cast<std::uint32_t>(__builtin_ctz(req.memoryTypeBits));
  VkDeviceMemory host_memory = VK_NULL_HANDLE;
  ASSERT_EQ(vkAllocateMemory(host.device, &ai, nullptr, &host_memory), VK_SUCCESS);
  ASSERT_EQ(vkBindBufferMemory(host.device, host_buffer, host_memory, 0), VK_SUCCESS);

  const auto xs = test::random_floats(n, 11);
  const auto ys = test::random_floats(n, 12);
  std::vector<float> result;
  {
    ExternalDevice ext;
    ext.instance = host.instance;
    ext.physical_device = host.physical;
    ext.device = host.device;
    ext.queue_family = host.family;
    ext.queue = host.queue;
    Device dev(ext, test::options());
    EXPECT_TRUE(dev.adopted());
    EXPECT_FALSE(dev.push_descriptors_enabled());  // the host did not enable it

    Tensor y = Tensor::wrap(dev, host_buffer, 0, {std::int64_t(n)});
    y.upload(ys);  // through staging: vkjr2 does not know the host's mapping
    Tensor x = Tensor::from(dev, {std::int64_t(n)}, xs);
    Stream s(dev);
    kernels::axpy(s, 2.0f, x, y);
    s.run();
    result = y.download();
  }
  for (std::size_t i = 0; i < n; ++i) ASSERT_FLOAT_EQ(result[i], std::fma(2.0f, xs[i], ys[i]));

  // The host's device and buffer are still alive and usable.
  EXPECT_EQ(vkDeviceWaitIdle(host.device), VK_SUCCESS);
  VkBuffer another = VK_NULL_HANDLE;
  EXPECT_EQ(vkCreateBuffer(host.device, &bi, nullptr, &another), VK_SUCCESS);
  vkDestroyBuffer(host.device, another, nullptr);
  vkDestroyBuffer(host.device, host_buffer, nullptr);
  vkFreeMemory(host.device, host_memory, nullptr);
  EXPECT_EQ(host.messages, 0);
}

TEST(Device, AdoptRejectsNullHandles) {
  ExternalDevice ext;
  EXPECT_THROW(Device dev(ext, test::options()), InvalidArgument);
}

}  // namespace
}  // namespace vkjr2
