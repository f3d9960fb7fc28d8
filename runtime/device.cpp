#include <vkjr2/runtime/device.hpp>
#include <vkjr2/runtime/device_core.hpp>

#include <algorithm>
#include <cctype>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <iostream>
#include <sstream>

namespace vkjr2 {
namespace detail {
namespace {

constexpr const char* kValidationLayer = "VK_LAYER_KHRONOS_validation";

std::string no_driver_fix() {
  std::string fix =
      "install a Vulkan driver: `apt-get install mesa-vulkan-drivers` for the CPU driver "
      "(lavapipe), or your GPU vendor's driver; `vulkaninfo --summary` (package vulkan-tools) "
      "shows what the loader finds";
  for (const char* var : {"VK_ICD_FILENAMES", "VK_DRIVER_FILES", "VK_ADD_DRIVER_FILES"}) {
    if (const char* value = std::getenv(var)) {
      fix += std::string("; note that ") + var + "='" + value + "' restricts the drivers searched";
    }
  }
  return fix;
}

bool has_extension(const std::vector<VkExtensionProperties>& exts, const char* name) {
  return std::any_of(exts.begin(), exts.end(), [name](const VkExtensionProperties& e) {
    return std::strcmp(e.extensionName, name) == 0;
  });
}

std::vector<VkExtensionProperties> device_extensions(VkPhysicalDevice pd) {
  std::uint32_t count = 0;
  vkEnumerateDeviceExtensionProperties(pd, nullptr, &count, nullptr);
  std::vector<VkExtensionProperties> exts(count);
  vkEnumerateDeviceExtensionProperties(pd, nullptr, &count, exts.data());
  exts.resize(count);
  return exts;
}

std::uint32_t instance_api_version() {
  std::uint32_t version = VK_API_VERSION_1_0;
  auto enumerate = reinterpret_cast<PFN_vkEnumerateInstanceVersion>(
      vkGetInstanceProcAddr(VK_NULL_HANDLE, "vkEnumerateInstanceVersion"));
  if (enumerate != nullptr) enumerate(&version);
  return version;
}

VkInstance create_instance(bool validation, const VkDebugUtilsMessengerCreateInfoEXT* messenger) {
  const std::uint32_t loader_version = instance_api_version();
  if (loader_version < VK_API_VERSION_1_1) {
    throw NoDeviceError("create Vulkan instance",
                        "the Vulkan loader supports only Vulkan 1.0; vkjr2 needs 1.1",
                        "install a current loader: `apt-get install libvulkan1`");
  }
  VkApplicationInfo app{VK_STRUCTURE_TYPE_APPLICATION_INFO};
  app.pApplicationName = "vkjr2";
  app.pEngineName = "vkjr2";
  app.apiVersion = std::min<std::uint32_t>(loader_version, VK_API_VERSION_1_3);

  std::vector<const char*> layers;
  std::vector<const char*> extensions;
  VkValidationFeatureEnableEXT enables[] = {
      VK_VALIDATION_FEATURE_ENABLE_SYNCHRONIZATION_VALIDATION_EXT};
  VkValidationFeaturesEXT features{VK_STRUCTURE_TYPE_VALIDATION_FEATURES_EXT};
  features.enabledValidationFeatureCount = 1;
  features.pEnabledValidationFeatures = enables;
  VkInstanceCreateInfo info{VK_STRUCTURE_TYPE_INSTANCE_CREATE_INFO};
  info.pApplicationInfo = &app;

  if (validation) {
    std::uint32_t count = 0;
    vkEnumerateInstanceLayerProperties(&count, nullptr);
    std::vector<VkLayerProperties> props(count);
    vkEnumerateInstanceLayerProperties(&count, props.data());
    const bool found = std::any_of(props.begin(), props.begin() + count, [](const auto& p) {
      return std::strcmp(p.layerName, kValidationLayer) == 0;
    });
    if (!found) {
      throw Error("create Vulkan instance",
                  "validation was requested (VKJR2_VALIDATION=1) but the layer " +
                      std::string(kValidationLayer) + " is not installed",
                  "`apt-get install vulkan-validationlayers`, or unset VKJR2_VALIDATION",
                  VK_ERROR_LAYER_NOT_PRESENT);
    }
    layers.push_back(kValidationLayer);
    extensions.push_back(VK_EXT_DEBUG_UTILS_EXTENSION_NAME);
    extensions.push_back(VK_EXT_VALIDATION_FEATURES_EXTENSION_NAME);
    features.pNext = messenger;
    info.pNext = &features;
  }
  info.enabledLayerCount = static_cast<std::uint32_t>(layers.size());
  info.ppEnabledLayerNames = layers.data();
  info.enabledExtensionCount = static_cast<std::uint32_t>(extensions.size());
  info.ppEnabledExtensionNames = extensions.data();

  VkInstance instance = VK_NULL_HANDLE;
  const VkResult r = vkCreateInstance(&info, nullptr, &instance);
  if (r == VK_ERROR_INCOMPATIBLE_DRIVER) {
    throw NoDeviceError("create Vulkan instance", "no Vulkan driver found", no_driver_fix(), r);
  }
  check(r, "create Vulkan instance");
  return instance;
}

std::vector<VkPhysicalDevice> physical_devices(VkInstance instance) {
  std::uint32_t count = 0;
  VkResult r = vkEnumeratePhysicalDevices(instance, &count, nullptr);
  if (r == VK_ERROR_INITIALIZATION_FAILED || count == 0) {
    throw NoDeviceError("enumerate Vulkan devices", "no Vulkan device found", no_driver_fix(), r);
  }
  check(r, "enumerate Vulkan devices");
  std::vector<VkPhysicalDevice> devices(count);
  check(vkEnumeratePhysicalDevices(instance, &count, devices.data()), "enumerate Vulkan devices");
  devices.resize(count);
  return devices;
}

int type_rank(VkPhysicalDeviceType type) {
  switch (type) {
    case VK_PHYSICAL_DEVICE_TYPE_DISCRETE_GPU:
      return 0;
    case VK_PHYSICAL_DEVICE_TYPE_INTEGRATED_GPU:
      return 1;
    case VK_PHYSICAL_DEVICE_TYPE_VIRTUAL_GPU:
      return 2;
    case VK_PHYSICAL_DEVICE_TYPE_CPU:
      return 3;
    default:
      return 4;
  }
}

std::string lower(std::string_view s) {
  std::string out(s);
  for (char& c : out) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  return out;
}

std::string device_list_text(const std::vector<DeviceInfo>& devices) {
  std::string text;
  for (const DeviceInfo& d : devices) {
    text += (text.empty() ? "" : ", ") + std::to_string(d.index) + ": " + d.name;
  }
  return text;
}

// Queue family with compute, preferring one with timestamps.
std::uint32_t compute_family(VkPhysicalDevice pd) {
  std::uint32_t count = 0;
  vkGetPhysicalDeviceQueueFamilyProperties(pd, &count, nullptr);
  std::vector<VkQueueFamilyProperties> families(count);
  vkGetPhysicalDeviceQueueFamilyProperties(pd, &count, families.data());
  std::uint32_t best = UINT32_MAX;
  for (std::uint32_t i = 0; i < count; ++i) {
    if ((families[i].queueFlags & VK_QUEUE_COMPUTE_BIT) == 0) continue;
    if (best == UINT32_MAX ||
        (families[best].timestampValidBits == 0 && families[i].timestampValidBits > 0)) {
      best = i;
    }
  }
  return best;
}

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

bool env_flag(const char* name) {
  const char* v = std::getenv(name);
  if (v == nullptr) return false;
  const std::string s = lower(v);
  return s == "1" || s == "true" || s == "on" || s == "yes";
}

DeviceInfo query_device_info(VkPhysicalDevice pd, std::uint32_t index) {
  DeviceInfo info;
  info.index = index;
  const auto exts = device_extensions(pd);
  VkPhysicalDeviceProperties props{};
  vkGetPhysicalDeviceProperties(pd, &props);

  VkPhysicalDeviceSubgroupProperties subgroup{
      VK_STRUCTURE_TYPE_PHYSICAL_DEVICE_SUBGROUP_PROPERTIES};
  VkPhysicalDeviceDriverProperties driver{VK_STRUCTURE_TYPE_PHYSICAL_DEVICE_DRIVER_PROPERTIES};
  VkPhysicalDeviceProperties2 props2{VK_STRUCTURE_TYPE_PHYSICAL_DEVICE_PROPERTIES_2};
  props2.pNext = &subgroup;
  const bool has_driver_props = props.apiVersion >= VK_API_VERSION_1_2 ||
                                has_extension(exts, VK_KHR_DRIVER_PROPERTIES_EXTENSION_NAME);
  if (has_driver_props) subgroup.pNext = &driver;
  if (props.apiVersion >= VK_API_VERSION_1_1) vkGetPhysicalDeviceProperties2(pd, &props2);

  info.name = props.deviceName;
  info.type = props.deviceType;
  info.vendor_id = props.vendorID;
  info.device_id = props.deviceID;
  info.api_version = props.apiVersion;
  if (has_driver_props) {
    info.driver_name = driver.driverName;
    info.driver_info = driver.driverInfo;
    info.driver_id = driver.driverID;
  }
  info.subgroup_size = subgroup.subgroupSize;
  info.subgroup_arithmetic =
      (subgroup.supportedStages & VK_SHADER_STAGE_COMPUTE_BIT) != 0 &&
      (subgroup.supportedOperations & VK_SUBGROUP_FEATURE_ARITHMETIC_BIT) != 0;
  const VkPhysicalDeviceLimits& l = props.limits;
  info.max_shared_memory_bytes = l.maxComputeSharedMemorySize;
  info.max_workgroup_invocations = l.maxComputeWorkGroupInvocations;
  for (int i = 0; i < 3; ++i) {
    info.max_workgroup_size[i] = l.maxComputeWorkGroupSize[i];
    info.max_workgroup_count[i] = l.maxComputeWorkGroupCount[i];
  }
  info.max_push_constant_bytes = l.maxPushConstantsSize;
  info.max_storage_buffer_range = l.maxStorageBufferRange;
  info.max_uniform_buffer_range = l.maxUniformBufferRange;
  info.max_texel_buffer_elements = l.maxTexelBufferElements;
  info.min_storage_buffer_offset_alignment = l.minStorageBufferOffsetAlignment;
  info.min_texel_buffer_offset_alignment = l.minTexelBufferOffsetAlignment;
  info.min_uniform_buffer_offset_alignment = l.minUniformBufferOffsetAlignment;
  info.non_coherent_atom_size = l.nonCoherentAtomSize;
  info.timestamp_period_ns = l.timestampPeriod;
  info.push_descriptor_support = has_extension(exts, VK_KHR_PUSH_DESCRIPTOR_EXTENSION_NAME);

  VkPhysicalDeviceMaintenance3Properties maint3{
      VK_STRUCTURE_TYPE_PHYSICAL_DEVICE_MAINTENANCE_3_PROPERTIES};
  VkPhysicalDeviceProperties2 p2{VK_STRUCTURE_TYPE_PHYSICAL_DEVICE_PROPERTIES_2};
  p2.pNext = &maint3;
  if (props.apiVersion >= VK_API_VERSION_1_1) vkGetPhysicalDeviceProperties2(pd, &p2);
  info.max_memory_allocation_bytes =
      maint3.maxMemoryAllocationSize != 0 ? maint3.maxMemoryAllocationSize : (1ull << 30);

  const std::uint32_t family = compute_family(pd);
  if (family != UINT32_MAX) {
    std::uint32_t count = 0;
    vkGetPhysicalDeviceQueueFamilyProperties(pd, &count, nullptr);
    std::vector<VkQueueFamilyProperties> families(count);
    vkGetPhysicalDeviceQueueFamilyProperties(pd, &count, families.data());
    info.timestamps = families[family].timestampValidBits > 0 && l.timestampPeriod > 0;
  }

  VkPhysicalDeviceMemoryProperties mem{};
  vkGetPhysicalDeviceMemoryProperties(pd, &mem);
  VkDeviceSize largest_local = 0;
  for (std::uint32_t h = 0; h < mem.memoryHeapCount; ++h) {
    const bool local = (mem.memoryHeaps[h].flags & VK_MEMORY_HEAP_DEVICE_LOCAL_BIT) != 0;
    info.heaps.push_back({mem.memoryHeaps[h].size, local});
    if (local) largest_local = std::max(largest_local, mem.memoryHeaps[h].size);
  }
  for (std::uint32_t t = 0; t < mem.memoryTypeCount; ++t) {
    const auto f = mem.memoryTypes[t].propertyFlags;
    const bool mappable_local =
        (f & VK_MEMORY_PROPERTY_DEVICE_LOCAL_BIT) && (f & VK_MEMORY_PROPERTY_HOST_VISIBLE_BIT);
    // A small host-visible window of a discrete GPU's memory (BAR) is not
    // unified memory: only a mappable type on the main heap counts.
    if (mappable_local && mem.memoryHeaps[mem.memoryTypes[t].heapIndex].size >= largest_local) {
      info.unified_memory = true;
    }
  }
  return info;
}

// Memory type for tensors: mappable device-local memory where it is the main
// heap (lavapipe, integrated GPUs), else plain device-local memory.
MemoryChoice choose_tensor_memory(VkPhysicalDevice pd, bool unified) {
  VkPhysicalDeviceMemoryProperties mem{};
  vkGetPhysicalDeviceMemoryProperties(pd, &mem);
  int best = -1;
  int best_score = -1;
  for (std::uint32_t t = 0; t < mem.memoryTypeCount; ++t) {
    const auto f = mem.memoryTypes[t].propertyFlags;
    const bool local = f & VK_MEMORY_PROPERTY_DEVICE_LOCAL_BIT;
    const bool visible = f & VK_MEMORY_PROPERTY_HOST_VISIBLE_BIT;
    const bool coherent = f & VK_MEMORY_PROPERTY_HOST_COHERENT_BIT;
    const bool cached = f & VK_MEMORY_PROPERTY_HOST_CACHED_BIT;
    if (f & (VK_MEMORY_PROPERTY_PROTECTED_BIT | VK_MEMORY_PROPERTY_LAZILY_ALLOCATED_BIT)) continue;
    int score = 0;
    if (unified) {
      if (!(local && visible)) continue;
      score = 4 * coherent + 2 * cached;
    } else {
      if (!local) continue;
      score = visible ? 0 : 4;  // prefer memory the BAR window does not limit
    }
    score = score * 16 + static_cast<int>(std::min<VkDeviceSize>(
                             mem.memoryHeaps[mem.memoryTypes[t].heapIndex].size >> 30, 15));
    if (score > best_score) {
      best_score = score;
      best = static_cast<int>(t);
    }
  }
  if (best < 0) {
    throw Error("choose device memory", "the device has no device-local memory type",
                "pick another device with VKJR2_DEVICE");
  }
  MemoryChoice c;
  c.type_index = static_cast<std::uint32_t>(best);
  c.heap_index = mem.memoryTypes[best].heapIndex;
  c.heap_size = mem.memoryHeaps[c.heap_index].size;
  const auto f = mem.memoryTypes[best].propertyFlags;
  c.host_visible = unified && (f & VK_MEMORY_PROPERTY_HOST_VISIBLE_BIT);
  c.host_coherent = f & VK_MEMORY_PROPERTY_HOST_COHERENT_BIT;
  return c;
}

MemoryChoice choose_staging_memory(VkPhysicalDevice pd) {
  VkPhysicalDeviceMemoryProperties mem{};
  vkGetPhysicalDeviceMemoryProperties(pd, &mem);
  int best = -1;
  int best_score = -1;
  for (std::uint32_t t = 0; t < mem.memoryTypeCount; ++t) {
    const auto f = mem.memoryTypes[t].propertyFlags;
    if (!(f & VK_MEMORY_PROPERTY_HOST_VISIBLE_BIT) || !(f & VK_MEMORY_PROPERTY_HOST_COHERENT_BIT)) {
      continue;
    }
    const int score = (f & VK_MEMORY_PROPERTY_HOST_CACHED_BIT) ? 2 : 1;
    if (score > best_score) {
      best_score = score;
      best = static_cast<int>(t);
    }
  }
  if (best < 0) {
    throw Error("choose staging memory", "the device has no host-visible coherent memory",
                "pick another device with VKJR2_DEVICE");
  }
  MemoryChoice c;
  c.type_index = static_cast<std::uint32_t>(best);
  c.heap_index = mem.memoryTypes[best].heapIndex;
  c.heap_size = mem.memoryHeaps[c.heap_index].size;
  c.host_visible = true;
  c.host_coherent = true;
  return c;
}

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
                                          info.max_memory_allocation_bytes);

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

std::string DeviceInfo::type_name() const {
  switch (type) {
    case VK_PHYSICAL_DEVICE_TYPE_DISCRETE_GPU:
      return "discrete GPU";
    case VK_PHYSICAL_DEVICE_TYPE_INTEGRATED_GPU:
      return "integrated GPU";
    case VK_PHYSICAL_DEVICE_TYPE_VIRTUAL_GPU:
      return "virtual GPU";
    case VK_PHYSICAL_DEVICE_TYPE_CPU:
      return "CPU";
    default:
      return "other";
  }
}

std::string DeviceInfo::api_version_string() const {
  return std::to_string(VK_API_VERSION_MAJOR(api_version)) + "." +
         std::to_string(VK_API_VERSION_MINOR(api_version)) + "." +
         std::to_string(VK_API_VERSION_PATCH(api_version));
}

std::vector<DeviceInfo> list_devices() {
  VkInstance instance = detail::create_instance(false, nullptr);
  std::vector<DeviceInfo> infos;
  try {
    const auto pds = detail::physical_devices(instance);
    for (std::uint32_t i = 0; i < pds.size(); ++i) {
      infos.push_back(detail::query_device_info(pds[i], i));
    }
  } catch (...) {
    vkDestroyInstance(instance, nullptr);
    throw;
  }
  vkDestroyInstance(instance, nullptr);
  return infos;
}

std::uint32_t select_device(const std::vector<DeviceInfo>& devices, std::string_view selector) {
  if (devices.empty()) {
    throw NoDeviceError("select device", "no Vulkan device found", detail::no_driver_fix());
  }
  if (selector.empty()) {
    std::uint32_t best = UINT32_MAX;
    for (std::uint32_t i = 0; i < devices.size(); ++i) {
      if (devices[i].api_version < VK_API_VERSION_1_1) continue;
      if (best == UINT32_MAX ||
          detail::type_rank(devices[i].type) < detail::type_rank(devices[best].type)) {
        best = i;
      }
    }
    if (best == UINT32_MAX) {
      throw NoDeviceError(
          "select device",
          "no device supports Vulkan 1.1 (found " + detail::device_list_text(devices) + ")",
          "update the Vulkan driver");
    }
    return best;
  }
  const bool numeric = std::all_of(selector.begin(), selector.end(), [](char c) {
    return std::isdigit(static_cast<unsigned char>(c));
  });
  if (numeric) {
    const unsigned long index = std::strtoul(std::string(selector).c_str(), nullptr, 10);
    if (index >= devices.size()) {
      throw InvalidArgument("select device",
                            "device index " + std::string(selector) + " is out of range (found " +
                                detail::device_list_text(devices) + ")",
                            "set VKJR2_DEVICE (or --device) to one of these indices or a name");
    }
    return static_cast<std::uint32_t>(index);
  }
  const std::string wanted = detail::lower(selector);
  for (std::uint32_t i = 0; i < devices.size(); ++i) {
    if (detail::lower(devices[i].name).find(wanted) != std::string::npos) return i;
  }
  throw InvalidArgument("select device",
                        "no device name contains '" + std::string(selector) + "' (found " +
                            detail::device_list_text(devices) + ")",
                        "set VKJR2_DEVICE (or --device) to an index or a part of a listed name; "
                        "`vkjr2 devices` lists them");
}

Device::Device(const DeviceOptions& options)
    : core_(std::make_shared<detail::DeviceCore>(options)) {}
Device::Device(const ExternalDevice& external, const DeviceOptions& options)
    : core_(std::make_shared<detail::DeviceCore>(external, options)) {}
Device::Device(std::shared_ptr<detail::DeviceCore> core) : core_(std::move(core)) {}

const DeviceInfo& Device::info() const { return core_->info; }
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
