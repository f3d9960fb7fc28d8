#include <vkjr2/runtime/device.hpp>

#include <algorithm>
#include <cctype>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <iostream>
#include <sstream>

#include "internal/device_core.hpp"

namespace vkjr2 {
namespace detail {
namespace {

VKAPI_ATTR VkBool32 VKAPI_CALL on_debug_message(VkDebugUtilsMessageSeverityFlagBitsEXT severity,
                                                VkDebugUtilsMessageTypeFlagsEXT types,
                                                const VkDebugUtilsMessengerCallbackDataEXT* data,
                                                void* user) {
  // Loader chatter (GENERAL) is not a validation finding; validation and
  // performance warnings and errors are.
  if ((types & (VK_DEBUG_UTILS_MESSAGE_TYPE_VALIDATION_BIT_EXT |
                VK_DEBUG_UTILS_MESSAGE_TYPE_PERFORMANCE_BIT_EXT)) == 0) {
    return VK_FALSE;
  }
  if (severity < VK_DEBUG_UTILS_MESSAGE_SEVERITY_WARNING_BIT_EXT) return VK_FALSE;
  auto* core = static_cast<DeviceCore*>(user);
  std::string msg =
      (severity >= VK_DEBUG_UTILS_MESSAGE_SEVERITY_ERROR_BIT_EXT) ? "error: " : "warning: ";
  msg += data->pMessage != nullptr ? data->pMessage : "(no text)";
  core->record_validation_message(std::move(msg));
  return VK_FALSE;
}

}  // namespace

DeviceCore::DeviceCore(const DeviceOptions& options) {
  on_validation_message_ = options.on_validation_message;
  init_instance(options.validation.value_or(env_flag("VKJR2_VALIDATION")));
  owns_instance = true;
  try {
    const auto pds = physical_devices(instance);
    std::vector<DeviceInfo> infos;
    for (std::uint32_t i = 0; i < pds.size(); ++i) infos.push_back(query_device_info(pds[i], i));
    std::string selector = options.selector;
    if (selector.empty()) {
      if (const char* env = std::getenv("VKJR2_DEVICE")) selector = env;
    }
    const std::uint32_t chosen = select_device(infos, selector);
    physical_device = pds[chosen];
    info = infos[chosen];
    queue_family = compute_family(physical_device);
    if (queue_family == UINT32_MAX) {
      throw NoDeviceError("create device", "device '" + info.name + "' has no compute queue",
                          "pick another device with VKJR2_DEVICE");
    }
    const bool want_push = options.push_descriptors && info.push_descriptor_support;
    std::vector<const char*> extensions;
    if (want_push) extensions.push_back(VK_KHR_PUSH_DESCRIPTOR_EXTENSION_NAME);
    const float priority = 1.0f;
    VkDeviceQueueCreateInfo queue_info{VK_STRUCTURE_TYPE_DEVICE_QUEUE_CREATE_INFO};
    queue_info.queueFamilyIndex = queue_family;
    queue_info.queueCount = 1;
    queue_info.pQueuePriorities = &priority;
    VkDeviceCreateInfo device_info{VK_STRUCTURE_TYPE_DEVICE_CREATE_INFO};
    device_info.queueCreateInfoCount = 1;
    device_info.pQueueCreateInfos = &queue_info;
    device_info.enabledExtensionCount = static_cast<std::uint32_t>(extensions.size());
    device_info.ppEnabledExtensionNames = extensions.data();
    check(vkCreateDevice(physical_device, &device_info, nullptr, &device),
          "create device '" + info.name + "'");
    owns_device = true;
    vkGetDeviceQueue(device, queue_family, 0, &queue);
    push_descriptors = want_push;
    init_common(options);
  } catch (...) {
    destroy();
    throw;
  }
}

DeviceCore::DeviceCore(const ExternalDevice& ext, const DeviceOptions& options) {
  if (ext.instance == VK_NULL_HANDLE || ext.physical_device == VK_NULL_HANDLE ||
      ext.device == VK_NULL_HANDLE || ext.queue == VK_NULL_HANDLE) {
    throw InvalidArgument("adopt host device",
                          "ExternalDevice needs instance, physical_device, device and queue",
                          "pass the handles your application created");
  }
  on_validation_message_ = options.on_validation_message;
  instance = ext.instance;
  physical_device = ext.physical_device;
  device = ext.device;
  queue = ext.queue;
  queue_family = ext.queue_family;
  info = query_device_info(physical_device, 0);
  const bool host_push =
      std::any_of(ext.enabled_extensions.begin(), ext.enabled_extensions.end(),
                  [](const std::string& e) { return e == VK_KHR_PUSH_DESCRIPTOR_EXTENSION_NAME; });
  push_descriptors = options.push_descriptors && host_push;
  try {
    init_common(options);
  } catch (...) {
    destroy();
    throw;
  }
}

void DeviceCore::init_instance(bool validation_requested) {
  VkDebugUtilsMessengerCreateInfoEXT messenger_info{
      VK_STRUCTURE_TYPE_DEBUG_UTILS_MESSENGER_CREATE_INFO_EXT};
  messenger_info.messageSeverity = VK_DEBUG_UTILS_MESSAGE_SEVERITY_WARNING_BIT_EXT |
                                   VK_DEBUG_UTILS_MESSAGE_SEVERITY_ERROR_BIT_EXT;
  messenger_info.messageType = VK_DEBUG_UTILS_MESSAGE_TYPE_GENERAL_BIT_EXT |
                               VK_DEBUG_UTILS_MESSAGE_TYPE_VALIDATION_BIT_EXT |
                               VK_DEBUG_UTILS_MESSAGE_TYPE_PERFORMANCE_BIT_EXT;
  messenger_info.pfnUserCallback = on_debug_message;
  messenger_info.pUserData = this;
  instance = create_instance(validation_requested, &messenger_info);
  validation = validation_requested;
  if (validation) {
    auto create = reinterpret_cast<PFN_vkCreateDebugUtilsMessengerEXT>(
        vkGetInstanceProcAddr(instance, "vkCreateDebugUtilsMessengerEXT"));
    if (create != nullptr) create(instance, &messenger_info, nullptr, &messenger_);
  }
}

void DeviceCore::init_common(const DeviceOptions& options) {
  if (info.api_version < VK_API_VERSION_1_1) {
    throw NoDeviceError("create device",
                        "device '" + info.name + "' supports only Vulkan " +
                            info.api_version_string() + "; vkjr2 needs 1.1",
                        "update the driver or pick another device with VKJR2_DEVICE");
  }
  traits = device_traits_for(info, options.traits_profile);
  profile = options.profile.value_or(env_flag("VKJR2_PROFILE"));
  if (profile && !info.timestamps) {
    std::fprintf(stderr, "vkjr2: VKJR2_PROFILE ignored: '%s' has no timestamp queries\n",
                 info.name.c_str());
    profile = false;
  }
  if (push_descriptors) {
    cmd_push_descriptor_set = reinterpret_cast<PFN_vkCmdPushDescriptorSetKHR>(
        vkGetDeviceProcAddr(device, "vkCmdPushDescriptorSetKHR"));
    push_descriptors = cmd_push_descriptor_set != nullptr;
  }
  staging = options.force_staging || !info.unified_memory;
  const MemoryChoice choice = choose_tensor_memory(physical_device, !staging);
  const VkDeviceSize alignment = std::max<VkDeviceSize>(
      {256, info.min_storage_buffer_offset_alignment, info.min_texel_buffer_offset_alignment,
       info.min_uniform_buffer_offset_alignment, info.non_coherent_atom_size});
  const VkBufferUsageFlags usage =
      VK_BUFFER_USAGE_STORAGE_BUFFER_BIT | VK_BUFFER_USAGE_UNIFORM_BUFFER_BIT |
      VK_BUFFER_USAGE_UNIFORM_TEXEL_BUFFER_BIT | VK_BUFFER_USAGE_STORAGE_TEXEL_BUFFER_BIT |
      VK_BUFFER_USAGE_TRANSFER_SRC_BIT | VK_BUFFER_USAGE_TRANSFER_DST_BIT;
  allocator = std::make_unique<Allocator>(device, choice, usage, options.block_bytes, alignment,
                                          info.max_memory_allocation_bytes, options.cache_memory);

  VkCommandPoolCreateInfo pool_info{VK_STRUCTURE_TYPE_COMMAND_POOL_CREATE_INFO};
  pool_info.flags = VK_COMMAND_POOL_CREATE_RESET_COMMAND_BUFFER_BIT;
  pool_info.queueFamilyIndex = queue_family;
  check(vkCreateCommandPool(device, &pool_info, nullptr, &transfer_pool_), "create command pool");
  VkCommandBufferAllocateInfo cmd_info{VK_STRUCTURE_TYPE_COMMAND_BUFFER_ALLOCATE_INFO};
  cmd_info.commandPool = transfer_pool_;
  cmd_info.level = VK_COMMAND_BUFFER_LEVEL_PRIMARY;
  cmd_info.commandBufferCount = 1;
  check(vkAllocateCommandBuffers(device, &cmd_info, &transfer_cmd_), "allocate command buffer");
  VkFenceCreateInfo fence_info{VK_STRUCTURE_TYPE_FENCE_CREATE_INFO};
  check(vkCreateFence(device, &fence_info, nullptr, &transfer_fence_), "create fence");
  VkPipelineCacheCreateInfo cache_info{VK_STRUCTURE_TYPE_PIPELINE_CACHE_CREATE_INFO};
  check(vkCreatePipelineCache(device, &cache_info, nullptr, &pipeline_cache_),
        "create pipeline cache");
}

DeviceCore::~DeviceCore() { destroy(); }

void DeviceCore::destroy() noexcept {
  if (device != VK_NULL_HANDLE) {
    vkDeviceWaitIdle(device);
    if (profile) {
      const std::string report = profile_report();
      if (!report.empty()) std::fprintf(stderr, "%s", report.c_str());
    }
    for (auto& [key, p] : pipelines_) vkDestroyPipeline(device, p.pipeline, nullptr);
    pipelines_.clear();
    for (auto& [key, layout] : pipeline_layouts_) vkDestroyPipelineLayout(device, layout, nullptr);
    pipeline_layouts_.clear();
    for (auto& [key, layout] : set_layouts_) vkDestroyDescriptorSetLayout(device, layout, nullptr);
    set_layouts_.clear();
    for (auto& [key, module] : modules_) vkDestroyShaderModule(device, module, nullptr);
    modules_.clear();
    if (pipeline_cache_ != VK_NULL_HANDLE) vkDestroyPipelineCache(device, pipeline_cache_, nullptr);
    pipeline_cache_ = VK_NULL_HANDLE;
    if (staging_allocator_) staging_allocator_->release(staging_);
    staging_ = {};
    staging_allocator_.reset();
    allocator.reset();
    if (transfer_fence_ != VK_NULL_HANDLE) vkDestroyFence(device, transfer_fence_, nullptr);
    transfer_fence_ = VK_NULL_HANDLE;
    if (transfer_pool_ != VK_NULL_HANDLE) vkDestroyCommandPool(device, transfer_pool_, nullptr);
    transfer_pool_ = VK_NULL_HANDLE;
    if (owns_device) vkDestroyDevice(device, nullptr);
    device = VK_NULL_HANDLE;
  }
  if (instance != VK_NULL_HANDLE && owns_instance) {
    if (messenger_ != VK_NULL_HANDLE) {
      auto destroy = reinterpret_cast<PFN_vkDestroyDebugUtilsMessengerEXT>(
          vkGetInstanceProcAddr(instance, "vkDestroyDebugUtilsMessengerEXT"));
      if (destroy != nullptr) destroy(instance, messenger_, nullptr);
      messenger_ = VK_NULL_HANDLE;
    }
    vkDestroyInstance(instance, nullptr);
  }
  instance = VK_NULL_HANDLE;
}

void DeviceCore::record_validation_message(std::string message) {
  if (on_validation_message_) {
    on_validation_message_(message);
  } else {
    std::fprintf(stderr, "vkjr2 validation %s\n", message.c_str());
  }
  std::lock_guard lock(messages_mutex_);
  messages_.push_back(std::move(message));
}

std::vector<std::string> DeviceCore::validation_messages() const {
  std::lock_guard lock(messages_mutex_);
  return messages_;
}

void DeviceCore::add_kernel_time(std::string_view kernel, double ns) {
  std::lock_guard lock(profile_mutex_);
  auto it = kernel_times_.find(kernel);
  if (it == kernel_times_.end())
    it = kernel_times_.emplace(std::string(kernel), KernelTime{}).first;
  it->second.calls += 1;
  it->second.total_ns += ns;
}

void DeviceCore::reset_profile() {
  std::lock_guard lock(profile_mutex_);
  kernel_times_.clear();
}

std::string DeviceCore::profile_report() const {
  std::lock_guard lock(profile_mutex_);
  if (kernel_times_.empty()) return {};
  std::vector<std::pair<std::string, KernelTime>> rows(kernel_times_.begin(), kernel_times_.end());
  std::sort(rows.begin(), rows.end(),
            [](const auto& a, const auto& b) { return a.second.total_ns > b.second.total_ns; });
  double total = 0;
  for (const auto& r : rows) total += r.second.total_ns;
  std::ostringstream os;
  char line[256];
  std::snprintf(line, sizeof line, "vkjr2 profile (%s): GPU time per kernel\n", info.name.c_str());
  os << line;
  std::snprintf(line, sizeof line, "  %-28s %8s %12s %12s %7s\n", "kernel", "calls", "total ms",
                "mean us", "share");
  os << line;
  for (const auto& [name, t] : rows) {
    std::snprintf(line, sizeof line, "  %-28s %8llu %12.3f %12.2f %6.1f%%\n", name.c_str(),
                  static_cast<unsigned long long>(t.calls), t.total_ns * 1e-6,
                  t.total_ns * 1e-3 / double(t.calls), 100.0 * t.total_ns / total);
    os << line;
  }
  return os.str();
}

}  // namespace detail

// ---- public API ---------------------------------------------------------------

Device::Device(const DeviceOptions& options)
    : core_(std::make_shared<detail::DeviceCore>(options)) {}
Device::Device(const ExternalDevice& external, const DeviceOptions& options)
    : core_(std::make_shared<detail::DeviceCore>(external, options)) {}
Device::Device(std::shared_ptr<detail::DeviceCore> core) : core_(std::move(core)) {}

const DeviceInfo& Device::info() const { return core_->info; }
const DeviceTraits& Device::traits() const { return core_->traits; }
VkInstance Device::vk_instance() const { return core_->instance; }
VkPhysicalDevice Device::vk_physical_device() const { return core_->physical_device; }
VkDevice Device::vk_device() const { return core_->device; }
VkQueue Device::vk_queue() const { return core_->queue; }
std::uint32_t Device::queue_family() const { return core_->queue_family; }
bool Device::adopted() const { return !core_->owns_device; }
bool Device::validation_enabled() const { return core_->validation; }
bool Device::profiling_enabled() const { return core_->profile; }
bool Device::push_descriptors_enabled() const { return core_->push_descriptors; }
bool Device::staging() const { return core_->staging; }
MemoryStats Device::memory_stats() const { return core_->allocator->stats(); }
void Device::release_cached_memory() const { core_->allocator->trim(); }
std::string Device::profile_report() const { return core_->profile_report(); }
void Device::reset_profile() const { core_->reset_profile(); }

std::vector<std::string> Device::validation_messages() const {
  return core_->validation_messages();
}
std::size_t Device::validation_message_count() const { return validation_messages().size(); }

void Device::wait_idle() const {
  std::lock_guard lock(core_->queue_mutex);
  check(vkDeviceWaitIdle(core_->device), "wait for device idle");
}

}  // namespace vkjr2
