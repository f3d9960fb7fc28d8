// Internal to the runtime (not installed): the block sub-allocator behind
// tensors. Each block is one VkDeviceMemory bound to one VkBuffer; a tensor is
// a range of a block.
#pragma once

#include <vkjr2/runtime/memory.hpp>

#include <vulkan/vulkan.h>

#include <cstddef>
#include <cstdint>
#include <map>
#include <memory>
#include <mutex>
#include <string_view>
#include <vector>

namespace vkjr2 {

namespace detail {

struct Block {
  VkDeviceMemory memory = VK_NULL_HANDLE;
  VkBuffer buffer = VK_NULL_HANDLE;
  VkDeviceSize size = 0;
  std::byte* mapped = nullptr;  // null when the memory is not host visible
  bool dedicated = false;       // one allocation larger than a block
  VkDeviceSize used = 0;
  std::map<VkDeviceSize, VkDeviceSize> free_ranges;  // offset → size, coalesced
};

struct Allocation {
  Block* block = nullptr;
  VkDeviceSize offset = 0;
  VkDeviceSize size = 0;
};

struct MemoryChoice {
  std::uint32_t type_index = 0;
  std::uint32_t heap_index = 0;
  VkDeviceSize heap_size = 0;
  bool host_visible = false;
  bool host_coherent = false;
};

class Allocator {
 public:
  Allocator(VkDevice device, MemoryChoice choice, VkBufferUsageFlags usage,
            VkDeviceSize block_bytes, VkDeviceSize alignment, VkDeviceSize max_allocation);
  ~Allocator();
  Allocator(const Allocator&) = delete;
  Allocator& operator=(const Allocator&) = delete;

  // Throws OutOfMemoryError (naming `what`, the size and what is free).
  Allocation allocate(VkDeviceSize bytes, std::string_view what);
  void release(const Allocation& allocation) noexcept;
  MemoryStats stats() const;
  const MemoryChoice& choice() const { return choice_; }

 private:
  Block* new_block(VkDeviceSize bytes, bool dedicated, std::string_view what);
  void destroy_block(Block& block) noexcept;

  VkDevice device_;
  MemoryChoice choice_;
  VkBufferUsageFlags usage_;
  VkDeviceSize block_bytes_;
  VkDeviceSize alignment_;
  VkDeviceSize max_allocation_;
  mutable std::mutex mutex_;
  std::vector<std::unique_ptr<Block>> blocks_;
  std::size_t allocations_ = 0;
};

}  // namespace detail
}  // namespace vkjr2
