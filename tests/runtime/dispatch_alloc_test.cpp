// The dispatch hot path allocates nothing: once a kernel's pipeline, its
// texel views and the stream's bookkeeping exist, recording the same
// dispatches again makes no C++ heap allocation (operator new is counted
// while a flag is set; the driver's own C allocations are not ours to count,
// and the validation layer is off here because it allocates per call).
// The replacements below pair malloc with free on purpose, which GCC's
// -Wmismatched-new-delete cannot see through once they are inlined.
#if defined(__GNUC__) && !defined(__clang__)
#pragma GCC diagnostic ignored "-Wmismatched-new-delete"
#endif

#include <vkjr2/kernels/basic.hpp>
#include <vkjr2/kernels/elementwise.hpp>
#include <vkjr2/runtime/device.hpp>
#include <vkjr2/runtime/stream.hpp>

#include <gtest/gtest.h>

#include <atomic>
#include <cstdlib>
#include <new>
#include <vector>

#include "support/test_device.hpp"

#if defined(__SANITIZE_ADDRESS__)
#define VKJR2_COUNT_NEW 0  // the sanitizer owns operator new
#elif defined(__has_feature)
#if __has_feature(address_sanitizer)
#define VKJR2_COUNT_NEW 0
#else
#define VKJR2_COUNT_NEW 1
#endif
#else
#define VKJR2_COUNT_NEW 1
#endif

namespace {
std::atomic<bool> g_counting{false};
std::atomic<long> g_news{0};
}  // namespace

#if VKJR2_COUNT_NEW
// Every allocating form forwards here (the others call these).
void* operator new(std::size_t size) {
  if (g_counting.load(std::memory_order_relaxed)) g_news.fetch_add(1, std::memory_order_relaxed);
  if (void* p = std::malloc(size == 0 ? 1 : size)) return p;
  throw std::bad_alloc();
}
void* operator new[](std::size_t size) { return operator new(size); }
void operator delete(void* p) noexcept { std::free(p); }
void operator delete[](void* p) noexcept { std::free(p); }
void operator delete(void* p, std::size_t) noexcept { std::free(p); }
void operator delete[](void* p, std::size_t) noexcept { std::free(p); }
#endif

namespace vkjr2 {
namespace {

TEST(Dispatch, RecordingAllocatesNothing) {
  if (!VKJR2_COUNT_NEW) GTEST_SKIP() << "operator new belongs to the sanitizer in this build";
  DeviceOptions options = test::options();
  options.validation = false;  // the layer allocates on every call
  const Device dev(options);
  std::vector<Tensor> a, b, c;
  for (int i = 0; i < 8; ++i) {
    a.push_back(Tensor::from(dev, {1000}, std::vector<float>(1000, 1.f)));
    b.push_back(Tensor::from(dev, {1000}, std::vector<float>(1000, 2.f)));
    c.push_back(Tensor::empty(dev, {1000}));
  }
  Stream s(dev);
  const auto record = [&] {
    for (int i = 0; i < 8; ++i) {
      kernels::add(s, a[i], b[i], c[i]);   // texel reads, spec constants
      kernels::axpy(s, 0.5f, c[i], a[i]);  // a dependency: a barrier
    }
  };
  record();  // pipelines, views, pools and vectors are made here
  s.run();
  record();
  s.run();
  g_news = 0;
  g_counting = true;
  record();
  g_counting = false;
  s.run();
  EXPECT_EQ(g_news.load(), 0) << "operator new calls while recording 16 dispatches";
  // The work was done: c = a + b, then a += c / 2, three times from a = 1, b = 2.
  EXPECT_EQ(c[0].download()[0], 6.75f);
  EXPECT_EQ(a[7].download()[0], 8.125f);
}

}  // namespace
}  // namespace vkjr2
