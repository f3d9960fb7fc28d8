// What the loader and the physical devices offer, before any device is made:
// the instance, enumeration, DeviceInfo, the choice of device by selector and
// the memory types tensors and staging use. device.cpp creates the device.
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

}  // namespace

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

namespace {

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

}  // namespace

bool env_flag(const char* name) {
  const char* v = std::getenv(name);
  if (v == nullptr) return false;
  const std::string s = lower(v);
  return s == "1" || s == "true" || s == "on" || s == "yes";
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

namespace {

// The memory type with the highest score (a negative score rules a type out);
// throws Error(op, problem) when none qualifies.
template <class Score>
MemoryChoice best_memory_type(VkPhysicalDevice pd, const char* op, const char* problem,
                              Score score_of) {
  VkPhysicalDeviceMemoryProperties mem{};
  vkGetPhysicalDeviceMemoryProperties(pd, &mem);
  int best = -1;
  int best_score = -1;
  for (std::uint32_t t = 0; t < mem.memoryTypeCount; ++t) {
    const VkMemoryType& type = mem.memoryTypes[t];
    const int score = score_of(type.propertyFlags, mem.memoryHeaps[type.heapIndex].size);
    if (score > best_score) {
      best_score = score;
      best = static_cast<int>(t);
    }
  }
  if (best < 0) throw Error(op, problem, "pick another device with VKJR2_DEVICE");
  MemoryChoice c;
  c.type_index = static_cast<std::uint32_t>(best);
  c.heap_index = mem.memoryTypes[best].heapIndex;
  c.heap_size = mem.memoryHeaps[c.heap_index].size;
  const VkMemoryPropertyFlags f = mem.memoryTypes[best].propertyFlags;
  c.host_visible = (f & VK_MEMORY_PROPERTY_HOST_VISIBLE_BIT) != 0;
  c.host_coherent = (f & VK_MEMORY_PROPERTY_HOST_COHERENT_BIT) != 0;
  return c;
}

}  // namespace

// Memory type for tensors: mappable device-local memory where it is the main
// heap (lavapipe, integrated GPUs), else plain device-local memory.
MemoryChoice choose_tensor_memory(VkPhysicalDevice pd, bool unified) {
  MemoryChoice c = best_memory_type(
      pd, "choose device memory", "the device has no device-local memory type",
      [unified](VkMemoryPropertyFlags f, VkDeviceSize heap_bytes) {
        const bool local = f & VK_MEMORY_PROPERTY_DEVICE_LOCAL_BIT;
        const bool visible = f & VK_MEMORY_PROPERTY_HOST_VISIBLE_BIT;
        const bool coherent = f & VK_MEMORY_PROPERTY_HOST_COHERENT_BIT;
        const bool cached = f & VK_MEMORY_PROPERTY_HOST_CACHED_BIT;
        if (f & (VK_MEMORY_PROPERTY_PROTECTED_BIT | VK_MEMORY_PROPERTY_LAZILY_ALLOCATED_BIT)) {
          return -1;
        }
        int score = 0;
        if (unified) {
          if (!(local && visible)) return -1;
          score = 4 * coherent + 2 * cached;
        } else {
          if (!local) return -1;
          score = visible ? 0 : 4;  // prefer memory the BAR window does not limit
        }
        return score * 16 + static_cast<int>(std::min<VkDeviceSize>(heap_bytes >> 30, 15));
      });
  c.host_visible = unified && c.host_visible;  // mapped only in unified mode
  return c;
}

MemoryChoice choose_staging_memory(VkPhysicalDevice pd) {
  return best_memory_type(pd, "choose staging memory",
                          "the device has no host-visible coherent memory",
                          [](VkMemoryPropertyFlags f, VkDeviceSize) {
                            if (!(f & VK_MEMORY_PROPERTY_HOST_VISIBLE_BIT) ||
                                !(f & VK_MEMORY_PROPERTY_HOST_COHERENT_BIT)) {
                              return -1;
                            }
                            return (f & VK_MEMORY_PROPERTY_HOST_CACHED_BIT) ? 2 : 1;
                          });
}

}  // namespace detail

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

}  // namespace vkjr2
