// The host application's own Vulkan objects, made with plain Vulkan and no
// vkjr2: instance, device, compute queue, buffers, a command buffer with
// its fence, semaphores. vkjr2 adopts them (main.cpp) and destroys none.
#pragma once

#include <vulkan/vulkan.h>

#include <cstdint>
#include <string>
#include <vector>

namespace host {

// Throws std::runtime_error naming the call when r is not VK_SUCCESS.
void check(VkResult r, const char* what);

struct Vulkan {
  VkInstance instance = VK_NULL_HANDLE;
  VkDebugUtilsMessengerEXT messenger = VK_NULL_HANDLE;
  VkPhysicalDevice physical = VK_NULL_HANDLE;
  VkDevice device = VK_NULL_HANDLE;
  std::uint32_t family = 0;
  VkQueue queue = VK_NULL_HANDLE;
  std::vector<std::string> device_extensions;  // what was enabled
  int validation_messages = 0;

  // validation: the Khronos layer with synchronization validation.
  explicit Vulkan(bool validation);
  ~Vulkan();
  Vulkan(const Vulkan&) = delete;
  Vulkan& operator=(const Vulkan&) = delete;

  VkSemaphore make_semaphore() const;
};

// A buffer in host-visible, coherent memory, mapped for its whole life.
struct Buffer {
  VkDevice device = VK_NULL_HANDLE;
  VkBuffer buffer = VK_NULL_HANDLE;
  VkDeviceMemory memory = VK_NULL_HANDLE;
  void* mapped = nullptr;

  Buffer(const Vulkan& vk, VkDeviceSize bytes, VkBufferUsageFlags usage);
  ~Buffer();
  Buffer(const Buffer&) = delete;
  Buffer& operator=(const Buffer&) = delete;
};

// One primary command buffer (resettable) and the fence of its submissions.
struct Commands {
  VkDevice device = VK_NULL_HANDLE;
  VkCommandPool pool = VK_NULL_HANDLE;
  VkCommandBuffer cmd = VK_NULL_HANDLE;
  VkFence fence = VK_NULL_HANDLE;

  explicit Commands(const Vulkan& vk);
  ~Commands();
  Commands(const Commands&) = delete;
  Commands& operator=(const Commands&) = delete;

  void begin() const;  // resets and begins cmd
};

}  // namespace host
