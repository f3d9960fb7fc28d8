#include <vkjr2/kernels/basic.hpp>
#include <vkjr2/runtime/stream.hpp>
#include <vkjr2/runtime/tensor.hpp>

#include <gtest/gtest.h>

#include <algorithm>
#include <string>
#include <vector>

#include "support/test_device.hpp"

namespace vkjr2 {
namespace {

TEST(Memory, FreedRangeIsReusedInTheSameBlock) {
  Device dev(test::options());
  Tensor a = Tensor::empty(dev, {1024});
  Tensor b = Tensor::empty(dev, {1024});
  EXPECT_EQ(a.vk_buffer(), b.vk_buffer());  // one block, sub-allocated
  EXPECT_NE(a.vk_offset(), b.vk_offset());
  const VkDeviceSize a_offset = a.vk_offset();
  a = Tensor();
  Tensor c = Tensor::empty(dev, {1024});
  EXPECT_EQ(c.vk_offset(), a_offset);
  EXPECT_EQ(dev.memory_stats().blocks, 1u);
  EXPECT_EQ(dev.memory_stats().allocations, 2u);
}

TEST(Memory, NeighbouringFreeRangesCoalesce) {
  Device dev(test::options());
  std::vector<Tensor> ts;
  for (int i = 0; i < 3; ++i) ts.push_back(Tensor::empty(dev, {256 * 1024}));  // 1 MiB each
  const VkDeviceSize first = ts[0].vk_offset();
  ts.clear();
  // 3 MiB fits only if the three freed 1 MiB ranges merged.
  Tensor big = Tensor::empty(dev, {3 * 256 * 1024});
  EXPECT_EQ(big.vk_offset(), first);
  EXPECT_EQ(dev.memory_stats().blocks, 1u);
}

TEST(Memory, LargeTensorGetsDedicatedBlockCachedForReuse) {
  DeviceOptions o = test::options();
  o.block_bytes = 4 << 20;
  Device dev(o);
  Tensor small = Tensor::empty(dev, {16});
  const auto before = dev.memory_stats();
  VkBuffer first = VK_NULL_HANDLE;
  {
    Tensor large = Tensor::empty(dev, {1 << 20});  // 4 MiB > block/2
    EXPECT_EQ(dev.memory_stats().blocks, before.blocks + 1);
    first = large.vk_buffer();
  }
  // Kept, empty, and handed out again to a request of the same size.
  EXPECT_EQ(dev.memory_stats().blocks, before.blocks + 1);
  EXPECT_EQ(dev.memory_stats().cached_bytes, before.cached_bytes + (4u << 20));
  {
    Tensor again = Tensor::empty(dev, {1 << 20});
    EXPECT_EQ(again.vk_buffer(), first);
    EXPECT_EQ(dev.memory_stats().cached_bytes, before.cached_bytes);
    // Too large for the cached block (more than a quarter of waste the other way round).
    Tensor twice = Tensor::empty(dev, {1 << 21});
    EXPECT_NE(twice.vk_buffer(), first);
  }
  dev.release_cached_memory();
  const auto after = dev.memory_stats();
  EXPECT_EQ(after.cached_bytes, 0u);
  EXPECT_EQ(after.blocks, before.blocks);
  EXPECT_EQ(after.used_bytes, before.used_bytes);
}

TEST(Memory, EmptySharedBlocksAreCachedOrGivenBack) {
  for (const bool cache : {true, false}) {
    DeviceOptions o = test::options();
    o.block_bytes = 4 << 20;
    o.cache_memory = cache;
    Device dev(o);
    {
      std::vector<Tensor> ts;
      for (int i = 0; i < 6; ++i) ts.push_back(Tensor::empty(dev, {512 * 1024}));  // 2 MiB each
      EXPECT_EQ(dev.memory_stats().blocks, 3u);
    }
    // Cached: all three kept; not cached: one kept for reuse.
    EXPECT_EQ(dev.memory_stats().blocks, cache ? 3u : 1u) << "cache " << cache;
    EXPECT_EQ(dev.memory_stats().cached_bytes, (cache ? 3u : 1u) * (4u << 20));
    EXPECT_EQ(dev.memory_stats().used_bytes, 0u);
  }
}

// The cache never makes an allocation fail that would fit without it: the
// empty blocks are given back first.
TEST(Memory, CachedBlocksAreGivenBackWhenTheHeapIsFull) {
  Device dev(test::options());
  const MemoryStats m = dev.memory_stats();
  const std::uint64_t heap = m.heap_bytes;
  const std::uint64_t max_alloc = dev.info().max_memory_allocation_bytes;
  // Two sizes that fit the heap alone but not together.
  const std::uint64_t a = std::min<std::uint64_t>(heap / 10 * 6, max_alloc) / 4 * 4;
  const std::uint64_t b = std::min<std::uint64_t>(heap / 10 * 7, max_alloc) / 4 * 4;
  ASSERT_GT(a + b, heap) << "the device's largest allocation is too small for this check";
  { Tensor first = Tensor::empty(dev, {std::int64_t(a / 4)}); }
  EXPECT_GE(dev.memory_stats().cached_bytes, a);
  Tensor second = Tensor::empty(dev, {std::int64_t(b / 4)});  // needs the cached block given back
  EXPECT_EQ(dev.memory_stats().cached_bytes, 0u);
  EXPECT_GE(dev.memory_stats().used_bytes, b);
}

TEST(Memory, OutOfMemoryNamesSizeAndFreeMemory) {
  Device dev(test::options());
  const std::uint64_t heap = dev.memory_stats().heap_bytes > 0 ? dev.memory_stats().heap_bytes
                                                               : dev.info().heaps[0].size_bytes;
  const std::int64_t too_many = std::int64_t(heap / 4 * 2);  // twice the heap, in floats
  try {
    Tensor t = Tensor::empty(dev, {too_many});
    FAIL() << "allocation larger than the heap succeeded";
  } catch (const OutOfMemoryError& e) {
    const std::string msg = e.what();
    EXPECT_GT(e.requested_bytes(), heap);
    EXPECT_NE(msg.find("GiB"), std::string::npos) << msg;
    EXPECT_NE(msg.find("allocate tensor"), std::string::npos) << msg;
    EXPECT_NE(msg.find("Fix:"), std::string::npos) << msg;
  }
  // The device still works afterwards.
  Tensor ok = Tensor::from(dev, {4}, std::vector<float>{1, 2, 3, 4});
  EXPECT_EQ(ok.download()[3], 4.f);
}

TEST(Memory, BindingOverStorageRangeLimitIsAClearError) {
  Device& dev = test::device();
  const std::int64_t n = std::int64_t(dev.info().max_storage_buffer_range / 4) + 1024;
  Tensor t = Tensor::empty(dev, {n});  // allocating is fine (maxBufferSize is larger)
  Stream s(dev);
  try {
    kernels::fill(s, t, 1.f);
    FAIL() << "dispatch over maxStorageBufferRange accepted";
  } catch (const InvalidArgument& e) {
    EXPECT_NE(std::string(e.what()).find("binding limit"), std::string::npos) << e.what();
  }
}

}  // namespace
}  // namespace vkjr2
