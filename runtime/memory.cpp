#include <vkjr2/runtime/error.hpp>
#include <vkjr2/runtime/memory.hpp>

#include <algorithm>
#include <string>

#include "internal/allocator.hpp"

namespace vkjr2::detail {
namespace {

VkDeviceSize align_up(VkDeviceSize value, VkDeviceSize alignment) {
  return (value + alignment - 1) / alignment * alignment;
}

}  // namespace

Allocator::Allocator(VkDevice device, MemoryChoice choice, VkBufferUsageFlags usage,
                     VkDeviceSize block_bytes, VkDeviceSize alignment, VkDeviceSize max_allocation,
                     bool cache)
    : device_(device),
      choice_(choice),
      usage_(usage),
      block_bytes_(block_bytes),
      alignment_(alignment),
      max_allocation_(max_allocation),
      cache_(cache) {}

Allocator::~Allocator() {
  for (auto& block : blocks_) destroy_block(*block);
}

void Allocator::destroy_block(Block& block) noexcept {
  if (block.buffer != VK_NULL_HANDLE) vkDestroyBuffer(device_, block.buffer, nullptr);
  if (block.memory != VK_NULL_HANDLE) vkFreeMemory(device_, block.memory, nullptr);
  block.buffer = VK_NULL_HANDLE;
  block.memory = VK_NULL_HANDLE;
}

Block* Allocator::new_block(VkDeviceSize bytes, bool dedicated, std::string_view what) {
  VkDeviceSize reserved = 0;
  for (const auto& b : blocks_) reserved += b->size;
  const VkDeviceSize free_bytes = choice_.heap_size > reserved ? choice_.heap_size - reserved : 0;
  auto oom = [&](const std::string& problem, VkResult result) {
    return OutOfMemoryError(
        std::string(what), bytes, free_bytes, problem,
        "process smaller inputs (fewer frames per batch, smaller images), free tensors that are "
        "no longer needed, or pick a device with more memory via VKJR2_DEVICE",
        result);
  };
  if (bytes > max_allocation_) {
    throw oom("asked for " + format_bytes(bytes) + ", more than the device's largest allocation (" +
                  format_bytes(max_allocation_) + ")",
              VK_ERROR_OUT_OF_DEVICE_MEMORY);
  }
  if (bytes > free_bytes) {
    throw oom("asked for " + format_bytes(bytes) + " but only " + format_bytes(free_bytes) +
                  " of the " + format_bytes(choice_.heap_size) + " memory heap is free (" +
                  format_bytes(reserved) + " held by vkjr2)",
              VK_ERROR_OUT_OF_DEVICE_MEMORY);
  }

  auto block = std::make_unique<Block>();
  block->size = bytes;
  block->dedicated = dedicated;
  VkBufferCreateInfo buffer_info{VK_STRUCTURE_TYPE_BUFFER_CREATE_INFO};
  buffer_info.size = bytes;
  buffer_info.usage = usage_;
  buffer_info.sharingMode = VK_SHARING_MODE_EXCLUSIVE;
  VkResult r = vkCreateBuffer(device_, &buffer_info, nullptr, &block->buffer);
  if (r != VK_SUCCESS) {
    throw oom("could not create a buffer of " + format_bytes(bytes), r);
  }
  VkMemoryRequirements req{};
  vkGetBufferMemoryRequirements(device_, block->buffer, &req);
  if ((req.memoryTypeBits & (1u << choice_.type_index)) == 0) {
    destroy_block(*block);
    throw Error(std::string(what), "the chosen memory type cannot hold storage buffers",
                "report this device (vulkaninfo output) as a bug");
  }
  VkMemoryAllocateInfo alloc_info{VK_STRUCTURE_TYPE_MEMORY_ALLOCATE_INFO};
  alloc_info.allocationSize = req.size;
  alloc_info.memoryTypeIndex = choice_.type_index;
  r = vkAllocateMemory(device_, &alloc_info, nullptr, &block->memory);
  if (r != VK_SUCCESS) {
    destroy_block(*block);
    throw oom("the driver could not allocate " + format_bytes(bytes), r);
  }
  r = vkBindBufferMemory(device_, block->buffer, block->memory, 0);
  if (r == VK_SUCCESS && choice_.host_visible) {
    void* ptr = nullptr;
    r = vkMapMemory(device_, block->memory, 0, VK_WHOLE_SIZE, 0, &ptr);
    block->mapped = static_cast<std::byte*>(ptr);
  }
  if (r != VK_SUCCESS) {
    destroy_block(*block);
    check(r, what);
  }
  block->free_ranges.emplace(0, bytes);
  blocks_.push_back(std::move(block));
  return blocks_.back().get();
}

Block* Allocator::new_block_or_trim(VkDeviceSize bytes, bool dedicated, std::string_view what) {
  try {
    return new_block(bytes, dedicated, what);
  } catch (const OutOfMemoryError&) {
    if (!trim_locked()) throw;  // nothing cached: the first answer stands
    return new_block(bytes, dedicated, what);
  }
}

Block* Allocator::cached_dedicated(VkDeviceSize bytes) {
  Block* best = nullptr;
  for (auto& b : blocks_) {
    if (!b->dedicated || b->used != 0 || b->size < bytes || b->size - bytes > bytes / 4) continue;
    if (best == nullptr || b->size < best->size) best = b.get();
  }
  return best;
}

void Allocator::trim() noexcept {
  std::lock_guard lock(mutex_);
  trim_locked();
}

bool Allocator::trim_locked() noexcept {
  for (auto& b : blocks_) {
    if (b->used == 0) destroy_block(*b);
  }
  return std::erase_if(blocks_, [](const std::unique_ptr<Block>& b) {
           return b->memory == VK_NULL_HANDLE;
         }) > 0;
}

Allocation Allocator::allocate(VkDeviceSize bytes, std::string_view what) {
  const VkDeviceSize size = align_up(std::max<VkDeviceSize>(bytes, 4), alignment_);
  std::lock_guard lock(mutex_);
  // Large requests get a block of their own (a cached one when one fits).
  if (size > block_bytes_ / 2) {
    Block* block = cached_dedicated(size);
    if (block == nullptr) block = new_block_or_trim(size, true, what);
    block->free_ranges.clear();
    block->used = size;
    ++allocations_;
    return {block, 0, size};
  }
  for (auto& block : blocks_) {
    if (block->dedicated) continue;
    for (auto it = block->free_ranges.begin(); it != block->free_ranges.end(); ++it) {
      if (it->second < size) continue;  // first fit; ranges are aligned already
      const VkDeviceSize offset = it->first;
      const VkDeviceSize rest = it->second - size;
      block->free_ranges.erase(it);
      if (rest > 0) block->free_ranges.emplace(offset + size, rest);
      block->used += size;
      ++allocations_;
      return {block.get(), offset, size};
    }
  }
  Block* block = new_block_or_trim(block_bytes_, false, what);
  block->free_ranges.clear();
  if (size < block_bytes_) block->free_ranges.emplace(size, block_bytes_ - size);
  block->used = size;
  ++allocations_;
  return {block, 0, size};
}

void Allocator::release(const Allocation& allocation) noexcept {
  if (allocation.block == nullptr) return;
  std::lock_guard lock(mutex_);
  Block* block = allocation.block;
  block->used -= allocation.size;
  --allocations_;
  if (!block->dedicated) {
    // Insert and coalesce with the neighbours.
    auto [it, inserted] = block->free_ranges.emplace(allocation.offset, allocation.size);
    (void)inserted;
    if (it != block->free_ranges.begin()) {
      auto prev = std::prev(it);
      if (prev->first + prev->second == it->first) {
        prev->second += it->second;
        block->free_ranges.erase(it);
        it = prev;
      }
    }
    auto next = std::next(it);
    if (next != block->free_ranges.end() && it->first + it->second == next->first) {
      it->second += next->second;
      block->free_ranges.erase(next);
    }
  }
  if (block->used != 0) return;
  // Without the cache, keep one empty shared block for reuse and give back the rest.
  const bool keep =
      cache_ ||
      (!block->dedicated &&
       std::none_of(blocks_.begin(), blocks_.end(), [block](const std::unique_ptr<Block>& b) {
         return b.get() != block && !b->dedicated && b->used == 0;
       }));
  if (keep) return;
  auto pos = std::find_if(blocks_.begin(), blocks_.end(),
                          [block](const std::unique_ptr<Block>& b) { return b.get() == block; });
  destroy_block(*block);
  blocks_.erase(pos);
}

MemoryStats Allocator::stats() const {
  std::lock_guard lock(mutex_);
  MemoryStats s;
  for (const auto& b : blocks_) {
    s.reserved_bytes += b->size;
    s.used_bytes += b->used;
    if (b->used == 0) s.cached_bytes += b->size;
  }
  s.blocks = blocks_.size();
  s.allocations = allocations_;
  s.heap_bytes = choice_.heap_size;
  return s;
}

}  // namespace vkjr2::detail
