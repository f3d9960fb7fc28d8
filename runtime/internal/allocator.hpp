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

// Blocks left empty are kept for reuse (cache = true): a training step frees
// and allocates the same gigabyte or so each time, and fresh driver memory
// costs page faults on first touch (lavapipe: 17 % of a co-training step).
// They are given back by trim(), and before any allocation that would
// otherwise not fit the heap or that the driver refuses.
class Allocator {
 public:
  Allocator(VkDevice device, MemoryChoice choice, VkBufferUsageFlags usage,
            VkDeviceSize block_bytes, VkDeviceSize alignment, VkDeviceSize max_allocation,
            bool cache);
  ~Allocator();
  Allocator(const Allocator&) = delete;
  Allocator& operator=(const Allocator&) = delete;

  // Throws OutOfMemoryError (naming `what`, the size and what is free).
  Allocation allocate(VkDeviceSize bytes, std::string_view what);
  void release(const Allocation& allocation) noexcept;
  // Gives every empty block back to the driver.
  void trim() noexcept;
  MemoryStats stats() const;
  const MemoryChoice& choice() const { return choice_; }

 private:
  Block* new_block(VkDeviceSize bytes, bool dedicated, std::string_view what);
  // A new block, after giving the empty ones back if it could not be had.
  Block* new_block_or_trim(VkDeviceSize bytes, bool dedicated, std::string_view what);
  // An empty dedicated block of at least `bytes` and at most a quarter more.
  Block* cached_dedicated(VkDeviceSize bytes);
  // Whether any block was given back.
  bool trim_locked() noexcept;
  void destroy_block(Block& block) noexcept;

  VkDevice device_;
  MemoryChoice choice_;
  VkBufferUsageFlags usage_;
  VkDeviceSize block_bytes_;
  VkDeviceSize alignment_;
  VkDeviceSize max_allocation_;
  bool cache_;
  mutable std::mutex mutex_;
  std::vector<std::unique_ptr<Block>> blocks_;
  std::size_t allocations_ = 0;
};

}  // namespace detail
}  // namespace vkjr2
