// Internal: the state behind a Device handle. Included by runtime/*.cpp only.
#pragma once

#include <vkjr2/runtime/device.hpp>
#include <vkjr2/runtime/kernel.hpp>

#include <vulkan/vulkan.h>

#include <algorithm>
#include <array>
#include <atomic>
#include <map>
#include <memory>
#include <mutex>
#include <span>
#include <string>
#include <string_view>
#include <unordered_map>
#include <vector>

#include "allocator.hpp"

namespace vkjr2::detail {

struct Pipeline {
  VkPipeline pipeline = VK_NULL_HANDLE;
  VkPipelineLayout layout = VK_NULL_HANDLE;
  VkDescriptorSetLayout set_layout = VK_NULL_HANDLE;
};

// The most specialization constants one dispatch may set.
inline constexpr std::size_t kMaxSpecConstants = 16;

// A pipeline's identity: the shader and its specialization constants. Looked
// up through PipelineKeyView, which borrows both, so that finding a pipeline
// that exists allocates nothing.
struct PipelineKey {
  std::string shader;
  std::array<std::uint32_t, kMaxSpecConstants> spec{};
  std::size_t spec_count = 0;
};
struct PipelineKeyView {
  std::string_view shader;
  std::span<const std::uint32_t> spec;
};
struct PipelineKeyHash {
  using is_transparent = void;
  std::size_t operator()(const PipelineKeyView& k) const noexcept;
  std::size_t operator()(const PipelineKey& k) const noexcept {
    return (*this)(PipelineKeyView{k.shader, {k.spec.data(), k.spec_count}});
  }
};
struct PipelineKeyEqual {
  using is_transparent = void;
  static PipelineKeyView view(const PipelineKey& k) noexcept {
    return {k.shader, {k.spec.data(), k.spec_count}};
  }
  static const PipelineKeyView& view(const PipelineKeyView& k) noexcept { return k; }
  template <class A, class B>
  bool operator()(const A& a, const B& b) const noexcept {
    const PipelineKeyView x = view(a), y = view(b);
    return x.shader == y.shader &&
           std::equal(x.spec.begin(), x.spec.end(), y.spec.begin(), y.spec.end());
  }
};

struct KernelTime {
  std::uint64_t calls = 0;
  double total_ns = 0;
};

class DeviceCore {
 public:
  DeviceCore(const DeviceOptions& options);
  DeviceCore(const ExternalDevice& external, const DeviceOptions& options);
  ~DeviceCore();
  DeviceCore(const DeviceCore&) = delete;
  DeviceCore& operator=(const DeviceCore&) = delete;

  // Lazily created, cached per (shader, specialization constants).
  const Pipeline& pipeline(const KernelDef& kernel, std::span<const std::uint32_t> spec);

  // Synchronous buffer-to-buffer copy through the one-shot command buffer
  // (used for staging); host-visible staging memory is managed here.
  void copy_host_to_buffer(const void* data, VkBuffer dst, VkDeviceSize dst_offset,
                           VkDeviceSize size);
  void copy_buffer_to_host(VkBuffer src, VkDeviceSize src_offset, void* data, VkDeviceSize size);

  void record_validation_message(std::string message);
  std::vector<std::string> validation_messages() const;
  void add_kernel_time(std::string_view kernel, double ns);
  std::string profile_report() const;
  void reset_profile();

  VkInstance instance = VK_NULL_HANDLE;
  VkPhysicalDevice physical_device = VK_NULL_HANDLE;
  VkDevice device = VK_NULL_HANDLE;
  VkQueue queue = VK_NULL_HANDLE;
  std::uint32_t queue_family = 0;
  DeviceInfo info;
  DeviceTraits traits;
  bool owns_instance = false;
  bool owns_device = false;
  bool validation = false;
  bool profile = false;
  bool push_descriptors = false;
  bool staging = false;  // tensors not host-mapped
  PFN_vkCmdPushDescriptorSetKHR cmd_push_descriptor_set = nullptr;
  std::unique_ptr<Allocator> allocator;
  std::mutex queue_mutex;  // vkQueueSubmit needs external synchronization

 private:
  void destroy() noexcept;
  void init_instance(bool validation_requested);
  void init_device();
  void init_common(const DeviceOptions& options);
  VkDescriptorSetLayout set_layout(const std::vector<BindingKind>& bindings);
  VkShaderModule shader_module(std::string_view name);
  void ensure_staging(VkDeviceSize bytes);
  void one_shot_copy(VkBuffer src, VkDeviceSize src_offset, VkBuffer dst, VkDeviceSize dst_offset,
                     VkDeviceSize size);

  VkDebugUtilsMessengerEXT messenger_ = VK_NULL_HANDLE;
  std::function<void(std::string_view)> on_validation_message_;
  mutable std::mutex messages_mutex_;
  std::vector<std::string> messages_;

  std::mutex pipelines_mutex_;
  std::unordered_map<PipelineKey, Pipeline, PipelineKeyHash, PipelineKeyEqual> pipelines_;
  std::map<std::vector<BindingKind>, VkDescriptorSetLayout> set_layouts_;
  std::map<std::string, VkPipelineLayout, std::less<>> pipeline_layouts_;
  std::map<std::string, VkShaderModule, std::less<>> modules_;
  VkPipelineCache pipeline_cache_ = VK_NULL_HANDLE;

  std::mutex staging_mutex_;
  std::unique_ptr<Allocator> staging_allocator_;
  Allocation staging_;
  VkCommandPool transfer_pool_ = VK_NULL_HANDLE;
  VkCommandBuffer transfer_cmd_ = VK_NULL_HANDLE;
  VkFence transfer_fence_ = VK_NULL_HANDLE;

  mutable std::mutex profile_mutex_;
  std::map<std::string, KernelTime, std::less<>> kernel_times_;
};

// The memory behind one or more tensors (views share it).
struct Storage {
  std::shared_ptr<DeviceCore> core;
  Allocation allocation;  // empty for host-owned buffers
  VkBuffer buffer = VK_NULL_HANDLE;
  VkDeviceSize base = 0;  // offset of this storage inside buffer
  VkDeviceSize size = 0;
  std::byte* mapped = nullptr;  // host pointer to `base`, null when not mapped

  struct View {
    VkFormat format;
    VkDeviceSize offset;
    VkDeviceSize range;
    VkBufferView view;
  };
  std::mutex views_mutex;
  std::vector<View> views;

  ~Storage() {
    for (const View& v : views) vkDestroyBufferView(core->device, v.view, nullptr);
    if (allocation.block != nullptr) core->allocator->release(allocation);
  }
};

// device_query.cpp: the loader and the physical devices. An instance (with
// the validation layer and a debug messenger when asked), the physical
// devices (NoDeviceError naming the driver to install when there is none), a
// DeviceInfo filled from one (used by list_devices too).
VkInstance create_instance(bool validation, const VkDebugUtilsMessengerCreateInfoEXT* messenger);
std::vector<VkPhysicalDevice> physical_devices(VkInstance instance);
// The queue family with compute, preferring one with timestamps (UINT32_MAX: none).
std::uint32_t compute_family(VkPhysicalDevice physical_device);
DeviceInfo query_device_info(VkPhysicalDevice physical_device, std::uint32_t index);
// Memory types for tensors (unified: mappable device-local) and for staging.
MemoryChoice choose_tensor_memory(VkPhysicalDevice physical_device, bool unified);
MemoryChoice choose_staging_memory(VkPhysicalDevice physical_device);
// Reads a boolean environment variable ("1", "true", "on", "yes").
bool env_flag(const char* name);

}  // namespace vkjr2::detail
