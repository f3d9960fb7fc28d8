#include <vkjr2/kernels/basic.hpp>
#include <vkjr2/kernels/ref/basic_ref.hpp>
#include <vkjr2/runtime/stream.hpp>

#include <gtest/gtest.h>

#include <cmath>
#include <cstring>

#include "support/host_vulkan.hpp"
#include "support/test_device.hpp"

namespace vkjr2 {
namespace {

// A chain of dependent dispatches in one command buffer: every step reads what
// the previous one wrote (read-after-write) and overwrites what an earlier
// step read (write-after-read). A missing barrier shows as a wrong number and
// as a synchronization-validation message.
void dependent_chain(const Device& dev) {
  constexpr std::int64_t n = 300'000;
  const auto a0 = test::random_floats(n, 21);
  const auto b0 = test::random_floats(n, 22);
  Tensor a = Tensor::from(dev, {n}, a0);
  Tensor b = Tensor::from(dev, {n}, b0);
  Tensor snapshot = Tensor::empty(dev, {n});
  std::vector<float> ra = a0, rb = b0;
  Stream s(dev);
  for (int step = 0; step < 20; ++step) {
    kernels::axpy(s, 0.5f, a, b);    // b += 0.5 a    (reads a, writes b)
    kernels::axpy(s, -0.25f, b, a);  // a -= 0.25 b   (RAW on b, WAR on a)
    ref::axpy(0.5f, ra, rb);
    ref::axpy(-0.25f, rb, ra);
  }
  kernels::copy(s, a, snapshot);  // read a ...
  kernels::fill(s, a, 7.f);       // ... then overwrite it (WAR)
  EXPECT_EQ(s.dispatches(), 42u);
  EXPECT_EQ(s.barriers(), 41u);  // every step depends on the one before
  s.run();
  const auto ga = a.download(), gb = b.download(), gs = snapshot.download();
  for (std::int64_t i = 0; i < n; ++i) {
    ASSERT_NEAR(gb[i], rb[i], 1e-5f) << "i=" << i;
    ASSERT_NEAR(gs[i], ra[i], 1e-5f) << "i=" << i;
    ASSERT_EQ(ga[i], 7.f) << "i=" << i;
  }
}

TEST(Stream, BarriersOrderDependentDispatches) { dependent_chain(test::device()); }

TEST(Stream, BarriersWithDescriptorPoolsInsteadOfPushDescriptors) {
  DeviceOptions o = test::options();
  o.push_descriptors = false;
  Device dev(o);
  ASSERT_FALSE(dev.push_descriptors_enabled());
  dependent_chain(dev);
}

TEST(Stream, IndependentDispatchesNeedNoBarrier) {
  Device& dev = test::device();
  Stream s(dev);
  std::vector<Tensor> ts;
  for (int i = 0; i < 8; ++i) ts.push_back(Tensor::empty(dev, {1000}));
  for (int i = 0; i < 8; ++i) kernels::fill(s, ts[i], float(i));
  EXPECT_EQ(s.barriers(), 0u);
  // Disjoint views of one tensor are independent too.
  Tensor big = Tensor::empty(dev, {4096});
  kernels::fill(s, big.view({2048}, 0), 1.f);
  kernels::fill(s, big.view({2048}, 2048), 2.f);
  EXPECT_EQ(s.barriers(), 0u);
  // Reading both halves after writing them is a hazard: one barrier.
  Tensor whole = Tensor::empty(dev, {4096});
  kernels::copy(s, big, whole);
  EXPECT_EQ(s.barriers(), 1u);
  s.run();
  for (int i = 0; i < 8; ++i) EXPECT_EQ(ts[i].download()[999], float(i));
  const auto w = whole.download();
  EXPECT_EQ(w[0], 1.f);
  EXPECT_EQ(w[4095], 2.f);
}

TEST(Stream, TransferCommandsAreOrderedWithDispatches) {
  Device& dev = test::device();
  const auto v = test::random_floats(5000, 3);
  Tensor a = Tensor::from(dev, {5000}, v);
  Tensor b = Tensor::empty(dev, {5000});
  Stream s(dev);
  s.fill(b, 0.f);               // transfer write
  kernels::axpy(s, 3.f, a, b);  // compute reads and writes b
  s.copy(b, a);                 // transfer reads b, writes a (read by axpy: WAR)
  s.run();
  const auto ga = a.download();
  for (int i = 0; i < 5000; ++i) ASSERT_FLOAT_EQ(ga[i], 3.f * v[i]);
}

TEST(Stream, ManyDispatchesAndReuseAfterWait) {
  DeviceOptions o = test::options();
  o.push_descriptors = false;  // also grows the descriptor pools
  Device dev(o);
  Tensor x = Tensor::from(dev, {64}, std::vector<float>(64, 1.f));
  Tensor y = Tensor::from(dev, {64}, std::vector<float>(64, 0.f));
  Stream s(dev);
  for (int round = 0; round < 2; ++round) {
    for (int i = 0; i < 300; ++i) kernels::axpy(s, 1.f, x, y);
    s.run();
  }
  EXPECT_EQ(y.download()[63], 600.f);
}

TEST(Stream, AsyncSubmitThenWait) {
  Device& dev = test::device();
  Tensor x = Tensor::empty(dev, {100000});
  Stream s(dev);
  kernels::fill(s, x, 2.5f);
  s.submit();
  EXPECT_THROW(kernels::fill(s, x, 1.f), Error);  // still in flight
  s.wait();
  EXPECT_EQ(x.download()[99999], 2.5f);
  s.wait();  // idempotent
}

TEST(Stream, KeepsTensorsAliveUntilWorkFinishes) {
  Device& dev = test::device();
  Tensor out = Tensor::empty(dev, {1});
  Stream s(dev);
  {
    Tensor temp = Tensor::from(dev, {3000}, std::vector<float>(3000, 1.f));
    kernels::sum(s, temp, out);
  }  // temp's handle is gone; the stream still holds its memory
  s.run();
  EXPECT_FLOAT_EQ(out.download()[0], 3000.f);
}

TEST(Stream, DispatchChecksBindingsAndPushConstants) {
  Device& dev = test::device();
  Stream s(dev);
  Tensor t = Tensor::empty(dev, {16});
  static const KernelDef two{"copy", {BindingKind::storage, BindingKind::storage}, 4};
  const std::uint32_t n = 16;
  EXPECT_THROW(s.dispatch(two, {in(t)}, n, Groups{1}), InvalidArgument);
  EXPECT_THROW(s.dispatch(two, {in(t), texel(t)}, n, Groups{1}), InvalidArgument);
  EXPECT_THROW(s.dispatch(two, {in(t), out(t)}, std::uint64_t{16}, Groups{1}), InvalidArgument);
  EXPECT_THROW(s.dispatch(two, {in(t), out(Tensor())}, n, Groups{1}), InvalidArgument);
  EXPECT_THROW(s.dispatch(two, {in(t), out(t)}, n, Groups{0}), InvalidArgument);
  Tensor unaligned = t.view({4}, 1);  // 4-byte offset, not a multiple of the alignment
  if (dev.info().min_storage_buffer_offset_alignment > 4) {
    EXPECT_THROW(s.dispatch(two, {in(unaligned), out(t.view({4}, 0))}, 4u, Groups{1}),
                 InvalidArgument);
  }
  static const KernelDef missing{"no_such_shader", {BindingKind::storage}, 0};
  EXPECT_THROW(s.dispatch(missing, {out(t)}, Groups{1}), Error);
  EXPECT_FALSE(s.recording());  // nothing was recorded by the failed calls
}

TEST(Stream, TensorsFromAnotherDeviceAreRejected) {
  Device other(test::options());
  Tensor foreign = Tensor::empty(other, {16});
  Stream s(test::device());
  EXPECT_THROW(kernels::fill(s, foreign, 1.f), InvalidArgument);
}

// --- a host application's command buffers, semaphores and fences ---------

// Records `src` → `dst` (the host's own transfer) into the host's buffer.
void record_host_copy(const test::HostCommandBuffer& cb, VkBuffer src, VkBuffer dst,
                      VkDeviceSize bytes) {
  cb.begin();
  const VkBufferCopy region{0, 0, bytes};
  vkCmdCopyBuffer(cb.cmd, src, dst, 1, &region);
  EXPECT_EQ(vkEndCommandBuffer(cb.cmd), VK_SUCCESS);
}

// Host copy → vkjr2 dispatch → host copy back, ordered only by the host's
// semaphores (no waits in between), then the host's fence.
TEST(Stream, SubmitWaitsForAndSignalsHostSemaphores) {
  test::HostVulkan host;
  ASSERT_NE(host.device, VK_NULL_HANDLE);
  constexpr std::size_t n = 50'001;
  constexpr VkDeviceSize bytes = n * sizeof(float);
  const auto xs = test::random_floats(n, 31);
  const auto ys = test::random_floats(n, 32);
  {
    test::HostBuffer staging(host, bytes), xb(host, bytes), yb(host, bytes), readback(host, bytes);
    std::memcpy(staging.mapped, xs.data(), bytes);
    std::memcpy(yb.mapped, ys.data(), bytes);
    test::HostCommandBuffer upload(host), download(host);
    const VkSemaphore uploaded = host.semaphore(), computed = host.semaphore();
    const VkFence done = host.fence(), done2 = host.fence();
    {
      Device dev(test::adopt(host), test::options());
      const Tensor x = Tensor::wrap(dev, xb.buffer, 0, {std::int64_t(n)});
      const Tensor y = Tensor::wrap(dev, yb.buffer, 0, {std::int64_t(n)});

      record_host_copy(upload, staging.buffer, xb.buffer, bytes);
      ASSERT_EQ(
          test::host_submit(host.queue, upload.cmd, VK_NULL_HANDLE, 0, uploaded, VK_NULL_HANDLE),
          VK_SUCCESS);
      Stream s(dev);
      kernels::axpy(s, 2.f, x, y);  // y += 2 x, x from the host's copy
      SubmitSync sync;
      sync.wait_semaphores = {uploaded};
      sync.wait_stages = {VK_PIPELINE_STAGE_COMPUTE_SHADER_BIT};
      sync.signal_semaphores = {computed};
      s.submit(sync);
      record_host_copy(download, yb.buffer, readback.buffer, bytes);
      ASSERT_EQ(test::host_submit(host.queue, download.cmd, computed,
                                  VK_PIPELINE_STAGE_TRANSFER_BIT, VK_NULL_HANDLE, done),
                VK_SUCCESS);
      ASSERT_EQ(vkWaitForFences(host.device, 1, &done, VK_TRUE, UINT64_MAX), VK_SUCCESS);
      const auto got = readback.floats();
      for (std::size_t i = 0; i < n; ++i) {
        ASSERT_FLOAT_EQ(got[i], std::fma(2.f, xs[i], ys[i])) << "i=" << i;
      }
      s.wait();

      // The host's fence alone: signalled once the stream's work has finished.
      kernels::axpy(s, -1.f, x, y);  // y = ys + x
      SubmitSync fenced;
      fenced.fence = done2;
      s.submit(fenced);
      ASSERT_EQ(vkWaitForFences(host.device, 1, &done2, VK_TRUE, UINT64_MAX), VK_SUCCESS);
      const auto y_now = yb.floats();
      for (std::size_t i = 0; i < n; ++i) {
        ASSERT_FLOAT_EQ(y_now[i], std::fma(-1.f, xs[i], std::fma(2.f, xs[i], ys[i]))) << i;
      }
      s.wait();
      EXPECT_THROW(s.submit(SubmitSync{{uploaded}, {0, 0}, {}, VK_NULL_HANDLE}), InvalidArgument);
    }
    // vkjr2 destroyed none of the host's objects: they are still usable.
    EXPECT_EQ(vkResetFences(host.device, 1, &done), VK_SUCCESS);
    vkDestroyFence(host.device, done, nullptr);
    vkDestroyFence(host.device, done2, nullptr);
    vkDestroySemaphore(host.device, uploaded, nullptr);
    vkDestroySemaphore(host.device, computed, nullptr);
  }
  EXPECT_EQ(host.messages, 0);
}

TEST(Stream, RecordsIntoHostCommandBuffers) {
  test::HostVulkan host;
  ASSERT_NE(host.device, VK_NULL_HANDLE);
  constexpr std::size_t n = 40'000;
  constexpr VkDeviceSize bytes = n * sizeof(float);
  const auto xs = test::random_floats(n, 41);
  const auto ys = test::random_floats(n, 42);
  {
    test::HostBuffer staging(host, bytes), xb(host, bytes), yb(host, bytes);
    std::memcpy(staging.mapped, xs.data(), bytes);
    std::memcpy(yb.mapped, ys.data(), bytes);
    test::HostCommandBuffer upload(host);
    const VkSemaphore uploaded = host.semaphore();
    test::HostQueue commands(host);
    {
      Device dev(test::adopt(host), test::options());
      const Tensor x = Tensor::wrap(dev, xb.buffer, 0, {std::int64_t(n)});
      const Tensor y = Tensor::wrap(dev, yb.buffer, 0, {std::int64_t(n)});
      record_host_copy(upload, staging.buffer, xb.buffer, bytes);
      ASSERT_EQ(
          test::host_submit(host.queue, upload.cmd, VK_NULL_HANDLE, 0, uploaded, VK_NULL_HANDLE),
          VK_SUCCESS);
      commands.wait_first = uploaded;

      Stream s(dev, commands);
      EXPECT_TRUE(s.host_commands());
      std::vector<float> rx = xs, ry = ys;
      Tensor temp = Tensor::empty(dev, {std::int64_t(n)});  // vkjr2-owned, in the same buffer
      for (int step = 0; step < 5; ++step) {
        kernels::axpy(s, 0.5f, x, y);    // RAW on y after the previous step
        kernels::axpy(s, -0.25f, y, x);  // RAW on y, WAR on x
        ref::axpy(0.5f, rx, ry);
        ref::axpy(-0.25f, ry, rx);
      }
      kernels::copy(s, y, temp);
      kernels::axpy(s, 1.f, temp, x);  // x += y
      ref::axpy(1.f, ry, rx);
      const VkFence unused = host.fence();
      EXPECT_THROW(s.submit(SubmitSync{{}, {}, {}, unused}), InvalidArgument);
      vkDestroyFence(host.device, unused, nullptr);
      s.run();
      EXPECT_EQ(commands.begins, 1);
      EXPECT_EQ(commands.submits, 1);
      EXPECT_EQ(commands.waits, 1);
      const auto gx = xb.floats(), gy = yb.floats();
      for (std::size_t i = 0; i < n; ++i) {
        ASSERT_NEAR(gy[i], ry[i], 1e-5f) << "i=" << i;
        ASSERT_NEAR(gx[i], rx[i], 1e-5f) << "i=" << i;
      }
      // The stream records again into the host's (reset) buffer.
      kernels::fill(s, temp, 3.f);
      s.run();
      EXPECT_EQ(commands.begins, 2);
      EXPECT_EQ(temp.download()[n - 1], 3.f);
      // Destroying a stream with work in flight waits through the host.
      kernels::fill(s, temp, 4.f);
      s.submit();
    }
    EXPECT_EQ(commands.waits, 3);
    vkDestroySemaphore(host.device, uploaded, nullptr);
  }
  EXPECT_EQ(host.messages, 0);
}

}  // namespace
}  // namespace vkjr2
