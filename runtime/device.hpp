// Device: the Vulkan instance, physical device, logical device and compute
// queue vkjr2 runs on, owned or adopted from a host application.
#pragma once

#include <vkjr2/runtime/device_traits.hpp>
#include <vkjr2/runtime/error.hpp>
#include <vkjr2/runtime/memory.hpp>

#include <vulkan/vulkan.h>

#include <array>
#include <cstdint>
#include <functional>
#include <memory>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

namespace vkjr2 {

namespace detail {
class DeviceCore;
}

struct MemoryHeapInfo {
  std::uint64_t size_bytes = 0;
  bool device_local = false;
};

// What vkjr2 knows about a physical device; queried once.
struct DeviceInfo {
  std::uint32_t index = 0;  // position in vkEnumeratePhysicalDevices
  std::string name;
  VkPhysicalDeviceType type = VK_PHYSICAL_DEVICE_TYPE_OTHER;
  std::string driver_name;  // "llvmpipe", "NVIDIA", ... (empty when unknown)
  std::string driver_info;  // "Mesa 22.3.6 (LLVM 15.0.6)"
  VkDriverId driver_id = static_cast<VkDriverId>(0);
  std::uint32_t vendor_id = 0;
  std::uint32_t device_id = 0;
  std::uint32_t api_version = 0;
  std::uint32_t subgroup_size = 0;
  bool subgroup_arithmetic = false;  // subgroupAdd & co. in compute shaders
  std::uint32_t max_shared_memory_bytes = 0;
  std::uint32_t max_workgroup_invocations = 0;
  std::array<std::uint32_t, 3> max_workgroup_size{};
  std::array<std::uint32_t, 3> max_workgroup_count{};
  std::uint32_t max_push_constant_bytes = 0;
  std::uint64_t max_storage_buffer_range = 0;
  std::uint64_t max_uniform_buffer_range = 0;
  std::uint64_t max_texel_buffer_elements = 0;
  std::uint64_t max_memory_allocation_bytes = 0;
  std::uint64_t min_storage_buffer_offset_alignment = 0;
  std::uint64_t min_texel_buffer_offset_alignment = 0;
  std::uint64_t min_uniform_buffer_offset_alignment = 0;
  std::uint64_t non_coherent_atom_size = 0;
  bool timestamps = false;  // timestamp queries on the compute queue
  double timestamp_period_ns = 0;
  bool unified_memory = false;  // device-local memory the host can map
  bool push_descriptor_support = false;
  std::vector<MemoryHeapInfo> heaps;

  std::string type_name() const;  // "discrete GPU", "CPU", ...
  std::string api_version_string() const;
};

// Options for creating a Device. Environment variables fill what is unset.
struct DeviceOptions {
  // Device to use: an index or a case-insensitive substring of the name.
  // Empty: VKJR2_DEVICE, else the best by type (discrete > integrated >
  // virtual > CPU).
  std::string selector;
  // Khronos validation layer (with synchronization validation). Unset:
  // VKJR2_VALIDATION=1 turns it on.
  std::optional<bool> validation;
  // Per-kernel GPU timing from timestamp queries. Unset: VKJR2_PROFILE=1.
  std::optional<bool> profile;
  // Use VK_KHR_push_descriptor where the device has it (else descriptor pools).
  bool push_descriptors = true;
  // Never map tensors directly, even on unified-memory devices: every
  // upload/download goes through a staging buffer (tests that path).
  bool force_staging = false;
  // Size of the memory blocks tensors are sub-allocated from.
  std::uint64_t block_bytes = 64ull << 20;
  // Keep blocks that become empty for the next allocations instead of giving
  // them back to the driver at once (see Device::release_cached_memory).
  bool cache_memory = true;
  // The tuning profile (runtime/device_traits.hpp): "lavapipe" or "gpu".
  // Empty: VKJR2_DEVICE_TRAITS, else chosen by the device's driver.
  std::string traits_profile;
  // Called for every validation message (warning or error). Unset: printed
  // to stderr. Counted in Device::validation_message_count() either way.
  std::function<void(std::string_view)> on_validation_message;
};

// Vulkan objects owned by a host application (e.g. a video pipeline) that
// vkjr2 should run on. vkjr2 destroys none of them; the host keeps them alive
// while the Device and everything made from it lives, and synchronizes its
// own use of the queue with vkjr2's (Vulkan requires external sync of queues).
struct ExternalDevice {
  VkInstance instance = VK_NULL_HANDLE;
  VkPhysicalDevice physical_device = VK_NULL_HANDLE;
  VkDevice device = VK_NULL_HANDLE;
  std::uint32_t queue_family = 0;
  VkQueue queue = VK_NULL_HANDLE;
  // Device extensions the host enabled (vkjr2 uses VK_KHR_push_descriptor
  // only when listed here).
  std::vector<std::string> enabled_extensions;
};

// A handle to a device. Copies share one device; tensors and streams keep it
// alive, so it is destroyed after the last of them.
class Device {
 public:
  explicit Device(const DeviceOptions& options = {});
  Device(const ExternalDevice& external, const DeviceOptions& options = {});
  explicit Device(std::shared_ptr<detail::DeviceCore> core);

  const DeviceInfo& info() const;
  // The device-dependent tuning choices the kernels use (device_traits.hpp).
  const DeviceTraits& traits() const;
  VkInstance vk_instance() const;
  VkPhysicalDevice vk_physical_device() const;
  VkDevice vk_device() const;
  VkQueue vk_queue() const;
  std::uint32_t queue_family() const;
  bool adopted() const;  // built around a host's VkDevice

  bool validation_enabled() const;
  bool profiling_enabled() const;
  bool push_descriptors_enabled() const;
  bool staging() const;  // tensors are not host-mapped; copies go through staging
  std::size_t validation_message_count() const;
  std::vector<std::string> validation_messages() const;

  MemoryStats memory_stats() const;
  // Gives the empty memory blocks kept for reuse back to the driver (a host
  // that shares the device can call it after vkjr2's work). Allocations that
  // would not fit otherwise do this themselves first.
  void release_cached_memory() const;
  // Per-kernel GPU times gathered so far (VKJR2_PROFILE=1), as a table.
  std::string profile_report() const;
  // Forgets the times gathered so far (e.g. model loading and warm-up runs).
  void reset_profile() const;
  void wait_idle() const;

  detail::DeviceCore& core() const { return *core_; }
  const std::shared_ptr<detail::DeviceCore>& shared_core() const { return core_; }

 private:
  std::shared_ptr<detail::DeviceCore> core_;
};

// Every Vulkan device the loader finds, in enumeration order. Throws
// NoDeviceError (with the package to install) when there is none.
std::vector<DeviceInfo> list_devices();

// Index into devices that `selector` (index or name substring; empty: best by
// type) picks; throws InvalidArgument naming the selector and the choices.
std::uint32_t select_device(const std::vector<DeviceInfo>& devices, std::string_view selector);

}  // namespace vkjr2
