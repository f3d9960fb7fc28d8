// Test support: a "host application's" own Vulkan instance (validation layer
// with synchronization validation; any message fails the running test),
// device, compute queue and buffers, created with plain Vulkan, for the
// adoption tests (ExternalDevice, Tensor::wrap, HostCommands, SubmitSync).
#pragma once

#include <gtest/gtest.h>
#include <vulkan/vulkan.h>

#include <cstdint>
#include <cstring>
#include <span>
#include <vector>

namespace vkjr2::test {

struct HostVulkan {
  VkInstance instance = VK_NULL_HANDLE;
  VkDebugUtilsMessengerEXT messenger = VK_NULL_HANDLE;
  VkPhysicalDevice physical = VK_NULL_HANDLE;
  VkDevice device = VK_NULL_HANDLE;
  std::uint32_t family = 0;
  VkQueue queue = VK_NULL_HANDLE;
  int messages = 0;

  static VKAPI_ATTR VkBool32 VKAPI_CALL callback(VkDebugUtilsMessageSeverityFlagBitsEXT /*sev*/,
                                                 VkDebugUtilsMessageTypeFlagsEXT types,
                                                 const VkDebugUtilsMessengerCallbackDataEXT* data,
                                                 void* user) {
    if ((types & VK_DEBUG_UTILS_MESSAGE_TYPE_GENERAL_BIT_EXT) != 0) return VK_FALSE;
    ++static_cast<HostVulkan*>(user)->messages;
    ADD_FAILURE() << "Vulkan validation (host objects): " << data->pMessage;
    return VK_FALSE;
  }

  HostVulkan() {
    VkApplicationInfo app{VK_STRUCTURE_TYPE_APPLICATION_INFO};
    app.apiVersion = VK_API_VERSION_1_1;
    const char* layer = "VK_LAYER_KHRONOS_validation";
    const char* exts[] = {VK_EXT_DEBUG_UTILS_EXTENSION_NAME,
                          VK_EXT_VALIDATION_FEATURES_EXTENSION_NAME};
    VkDebugUtilsMessengerCreateInfoEXT mi{VK_STRUCTURE_TYPE_DEBUG_UTILS_MESSENGER_CREATE_INFO_EXT};
    mi.messageSeverity = VK_DEBUG_UTILS_MESSAGE_SEVERITY_WARNING_BIT_EXT |
                         VK_DEBUG_UTILS_MESSAGE_SEVERITY_ERROR_BIT_EXT;
    mi.messageType = VK_DEBUG_UTILS_MESSAGE_TYPE_VALIDATION_BIT_EXT |
                     VK_DEBUG_UTILS_MESSAGE_TYPE_PERFORMANCE_BIT_EXT;
    mi.pfnUserCallback = callback;
    mi.pUserData = this;
    const VkValidationFeatureEnableEXT sync =
        VK_VALIDATION_FEATURE_ENABLE_SYNCHRONIZATION_VALIDATION_EXT;
    VkValidationFeaturesEXT features{VK_STRUCTURE_TYPE_VALIDATION_FEATURES_EXT};
    features.enabledValidationFeatureCount = 1;
    features.pEnabledValidationFeatures = &sync;
    features.pNext = &mi;
    VkInstanceCreateInfo ii{VK_STRUCTURE_TYPE_INSTANCE_CREATE_INFO};
    ii.pNext = &features;
    ii.pApplicationInfo = &app;
    ii.enabledLayerCount = 1;
    ii.ppEnabledLayerNames = &layer;
    ii.enabledExtensionCount = 2;
    ii.ppEnabledExtensionNames = exts;
    EXPECT_EQ(vkCreateInstance(&ii, nullptr, &instance), VK_SUCCESS);
    auto create = reinterpret_cast<PFN_vkCreateDebugUtilsMessengerEXT>(
        vkGetInstanceProcAddr(instance, "vkCreateDebugUtilsMessengerEXT"));
    create(instance, &mi, nullptr, &messenger);
    std::uint32_t count = 1;
    vkEnumeratePhysicalDevices(instance, &count, &physical);
    std::uint32_t nf = 0;
    vkGetPhysicalDeviceQueueFamilyProperties(physical, &nf, nullptr);
    std::vector<VkQueueFamilyProperties> fams(nf);
    vkGetPhysicalDeviceQueueFamilyProperties(physical, &nf, fams.data());
    for (std::uint32_t i = 0; i < nf; ++i) {
      if ((fams[i].queueFlags & VK_QUEUE_COMPUTE_BIT) != 0) {
        family = i;
        break;
      }
    }
    const float prio = 1.f;
    VkDeviceQueueCreateInfo qi{VK_STRUCTURE_TYPE_DEVICE_QUEUE_CREATE_INFO};
    qi.queueFamilyIndex = family;
    qi.queueCount = 1;
    qi.pQueuePriorities = &prio;
    VkDeviceCreateInfo di{VK_STRUCTURE_TYPE_DEVICE_CREATE_INFO};
    di.queueCreateInfoCount = 1;
    di.pQueueCreateInfos = &qi;
    EXPECT_EQ(vkCreateDevice(physical, &di, nullptr, &device), VK_SUCCESS);
    vkGetDeviceQueue(device, family, 0, &queue);
  }
  ~HostVulkan() {
    vkDestroyDevice(device, nullptr);
    auto destroy = reinterpret_cast<PFN_vkDestroyDebugUtilsMessengerEXT>(
        vkGetInstanceProcAddr(instance, "vkDestroyDebugUtilsMessengerEXT"));
    destroy(instance, messenger, nullptr);
    vkDestroyInstance(instance, nullptr);
  }
  HostVulkan(const HostVulkan&) = delete;
  HostVulkan& operator=(const HostVulkan&) = delete;

  VkSemaphore semaphore() const {
    VkSemaphoreCreateInfo si{VK_STRUCTURE_TYPE_SEMAPHORE_CREATE_INFO};
    VkSemaphore s = VK_NULL_HANDLE;
    EXPECT_EQ(vkCreateSemaphore(device, &si, nullptr, &s), VK_SUCCESS);
    return s;
  }
  VkFence fence() const {
    VkFenceCreateInfo fi{VK_STRUCTURE_TYPE_FENCE_CREATE_INFO};
    VkFence f = VK_NULL_HANDLE;
    EXPECT_EQ(vkCreateFence(device, &fi, nullptr, &f), VK_SUCCESS);
    return f;
  }
};

// A host-visible, mapped buffer of the host's (storage + transfer usage).
struct HostBuffer {
  VkDevice device = VK_NULL_HANDLE;
  VkBuffer buffer = VK_NULL_HANDLE;
  VkDeviceMemory memory = VK_NULL_HANDLE;
  VkDeviceSize size_bytes = 0;
  void* mapped = nullptr;

  HostBuffer(const HostVulkan& host, VkDeviceSize size) : device(host.device), size_bytes(size) {
    VkBufferCreateInfo bi{VK_STRUCTURE_TYPE_BUFFER_CREATE_INFO};
    bi.size = size;
    bi.usage = VK_BUFFER_USAGE_STORAGE_BUFFER_BIT | VK_BUFFER_USAGE_UNIFORM_TEXEL_BUFFER_BIT |
               VK_BUFFER_USAGE_TRANSFER_SRC_BIT | VK_BUFFER_USAGE_TRANSFER_DST_BIT;
    EXPECT_EQ(vkCreateBuffer(device, &bi, nullptr, &buffer), VK_SUCCESS);
    VkMemoryRequirements req{};
    vkGetBufferMemoryRequirements(device, buffer, &req);
    VkPhysicalDeviceMemoryProperties props{};
    vkGetPhysicalDeviceMemoryProperties(host.physical, &props);
    const VkMemoryPropertyFlags want =
        VK_MEMORY_PROPERTY_HOST_VISIBLE_BIT | VK_MEMORY_PROPERTY_HOST_COHERENT_BIT;
    std::uint32_t type = 0;
    for (std::uint32_t i = 0; i < props.memoryTypeCount; ++i) {
      if ((req.memoryTypeBits & (1u << i)) != 0 &&
          (props.memoryTypes[i].propertyFlags & want) == want) {
        type = i;
        break;
      }
    }
    VkMemoryAllocateInfo ai{VK_STRUCTURE_TYPE_MEMORY_ALLOCATE_INFO};
    ai.allocationSize = req.size;
    ai.memoryTypeIndex = type;
    EXPECT_EQ(vkAllocateMemory(device, &ai, nullptr, &memory), VK_SUCCESS);
    EXPECT_EQ(vkBindBufferMemory(device, buffer, memory, 0), VK_SUCCESS);
    EXPECT_EQ(vkMapMemory(device, memory, 0, VK_WHOLE_SIZE, 0, &mapped), VK_SUCCESS);
  }
  ~HostBuffer() {
    vkDestroyBuffer(device, buffer, nullptr);
    vkFreeMemory(device, memory, nullptr);
  }
  HostBuffer(const HostBuffer&) = delete;
  HostBuffer& operator=(const HostBuffer&) = delete;

  std::span<float> floats() const {
    return {static_cast<float*>(mapped), std::size_t(size_bytes / sizeof(float))};
  }
};

// The host's command pool with one primary command buffer.
struct HostCommandBuffer {
  VkDevice device = VK_NULL_HANDLE;
  VkCommandPool pool = VK_NULL_HANDLE;
  VkCommandBuffer cmd = VK_NULL_HANDLE;

  explicit HostCommandBuffer(const HostVulkan& host) : device(host.device) {
    VkCommandPoolCreateInfo pi{VK_STRUCTURE_TYPE_COMMAND_POOL_CREATE_INFO};
    pi.flags = VK_COMMAND_POOL_CREATE_RESET_COMMAND_BUFFER_BIT;
    pi.queueFamilyIndex = host.family;
    EXPECT_EQ(vkCreateCommandPool(device, &pi, nullptr, &pool), VK_SUCCESS);
    VkCommandBufferAllocateInfo ai{VK_STRUCTURE_TYPE_COMMAND_BUFFER_ALLOCATE_INFO};
    ai.commandPool = pool;
    ai.level = VK_COMMAND_BUFFER_LEVEL_PRIMARY;
    ai.commandBufferCount = 1;
    EXPECT_EQ(vkAllocateCommandBuffers(device, &ai, &cmd), VK_SUCCESS);
  }
  ~HostCommandBuffer() { vkDestroyCommandPool(device, pool, nullptr); }
  HostCommandBuffer(const HostCommandBuffer&) = delete;
  HostCommandBuffer& operator=(const HostCommandBuffer&) = delete;

  void begin() const {
    vkResetCommandBuffer(cmd, 0);
    VkCommandBufferBeginInfo bi{VK_STRUCTURE_TYPE_COMMAND_BUFFER_BEGIN_INFO};
    bi.flags = VK_COMMAND_BUFFER_USAGE_ONE_TIME_SUBMIT_BIT;
    EXPECT_EQ(vkBeginCommandBuffer(cmd, &bi), VK_SUCCESS);
  }
};

// Submits `cmd` (ended) waiting for `wait` at `stage` and signalling `signal`.
inline VkResult host_submit(VkQueue queue, VkCommandBuffer cmd, VkSemaphore wait,
                            VkPipelineStageFlags stage, VkSemaphore signal, VkFence fence) {
  VkSubmitInfo si{VK_STRUCTURE_TYPE_SUBMIT_INFO};
  si.waitSemaphoreCount = wait != VK_NULL_HANDLE ? 1 : 0;
  si.pWaitSemaphores = &wait;
  si.pWaitDstStageMask = &stage;
  si.commandBufferCount = 1;
  si.pCommandBuffers = &cmd;
  si.signalSemaphoreCount = signal != VK_NULL_HANDLE ? 1 : 0;
  si.pSignalSemaphores = &signal;
  return vkQueueSubmit(queue, 1, &si, fence);
}

// The ExternalDevice that hands `host`'s objects to vkjr2.
inline ExternalDevice adopt(const HostVulkan& host) {
  ExternalDevice ext;
  ext.instance = host.instance;
  ext.physical_device = host.physical;
  ext.device = host.device;
  ext.queue_family = host.family;
  ext.queue = host.queue;
  return ext;
}

// The host's side of HostCommands: one command buffer and fence; the first
// submission waits for the host's upload semaphore.
class HostQueue final : public HostCommands {
 public:
  explicit HostQueue(const HostVulkan& host) : host_(host), cb_(host), fence_(host.fence()) {}
  ~HostQueue() override { vkDestroyFence(host_.device, fence_, nullptr); }
  HostQueue(const HostQueue&) = delete;
  HostQueue& operator=(const HostQueue&) = delete;

  VkCommandBuffer begin() override {
    ++begins;
    cb_.begin();
    return cb_.cmd;
  }
  void submit(VkCommandBuffer cmd) override {
    ++submits;
    EXPECT_EQ(cmd, cb_.cmd);
    EXPECT_EQ(vkEndCommandBuffer(cmd), VK_SUCCESS);
    EXPECT_EQ(host_submit(host_.queue, cmd, wait_first,
                          VK_PIPELINE_STAGE_COMPUTE_SHADER_BIT | VK_PIPELINE_STAGE_TRANSFER_BIT,
                          VK_NULL_HANDLE, fence_),
              VK_SUCCESS);
    wait_first = VK_NULL_HANDLE;
  }
  void wait() override {
    ++waits;
    EXPECT_EQ(vkWaitForFences(host_.device, 1, &fence_, VK_TRUE, UINT64_MAX), VK_SUCCESS);
    EXPECT_EQ(vkResetFences(host_.device, 1, &fence_), VK_SUCCESS);
  }

  VkSemaphore wait_first = VK_NULL_HANDLE;
  int begins = 0, submits = 0, waits = 0;

 private:
  const HostVulkan& host_;
  HostCommandBuffer cb_;
  VkFence fence_;
};

}  // namespace vkjr2::test
