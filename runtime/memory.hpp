// Device memory statistics (Device::memory_stats). Tensors are sub-allocated
// from large blocks, each one VkDeviceMemory bound to one VkBuffer; the
// allocator is internal (runtime/internal/allocator.hpp).
#pragma once

#include <cstddef>
#include <cstdint>

namespace vkjr2 {

struct MemoryStats {
  std::uint64_t reserved_bytes = 0;  // in VkDeviceMemory blocks
  std::uint64_t used_bytes = 0;      // handed out to live tensors
  // Part of reserved_bytes: empty blocks kept for reuse
  // (Device::release_cached_memory gives them back).
  std::uint64_t cached_bytes = 0;
  std::size_t blocks = 0;
  std::size_t allocations = 0;
  std::uint64_t heap_bytes = 0;  // size of the heap blocks come from
};

}  // namespace vkjr2
