// Stream: records many dispatches and copies into one command buffer,
// inserting the barriers that data hazards need, then submits them — on
// vkjr2's own command buffers, or on a host application's (HostCommands),
// ordered against the host's work by its semaphores and fences (SubmitSync).
#pragma once

#include <vkjr2/runtime/kernel.hpp>

#include <cstdint>
#include <initializer_list>
#include <memory>
#include <type_traits>
#include <vector>

namespace vkjr2 {

// The host's semaphores and fence for one submission of a Stream's own
// command buffer. vkjr2 neither creates, resets nor destroys any of them.
struct SubmitSync {
  std::vector<VkSemaphore> wait_semaphores;  // the stream's work waits for these
  // One stage mask per wait semaphore; empty: compute + transfer for each.
  std::vector<VkPipelineStageFlags> wait_stages;
  std::vector<VkSemaphore> signal_semaphores;  // signalled when the work has finished
  VkFence fence = VK_NULL_HANDLE;              // unsignalled; signalled when it has finished
};

// Command buffers owned by the host application that a Stream records into
// instead of its own: the host allocates, begins, ends, submits (with its
// own semaphores and fences) and frees them; vkjr2 only records. The
// stream keeps every tensor its recorded work uses alive until wait()
// returns, and calls wait() before it is destroyed.
class HostCommands {
 public:
  virtual ~HostCommands() = default;
  // A primary command buffer of the device's queue family, already begun.
  virtual VkCommandBuffer begin() = 0;
  // vkjr2 has finished recording into `cmd` (the buffer begin() returned):
  // end it and submit it. May return before the work has finished.
  virtual void submit(VkCommandBuffer cmd) = 0;
  // Return once the last submitted buffer's work has finished (e.g. wait for
  // the host's fence). The stream then reuses begin() for what it records next.
  virtual void wait() = 0;
};

class Stream {
 public:
  explicit Stream(const Device& device);
  // Records into `host`'s command buffers; `host` must outlive the stream.
  Stream(const Device& device, HostCommands& host);
  ~Stream();  // waits for submitted work; never throws
  Stream(const Stream&) = delete;
  Stream& operator=(const Stream&) = delete;
  Stream(Stream&&) noexcept;
  Stream& operator=(Stream&&) noexcept;

  // Records a dispatch of `kernel` with `args` bound to bindings 0..n-1,
  // `push` as push constants and `spec` as specialization constants 0..m-1.
  // Shapes, binding kinds and sizes are checked here.
  template <class Push>
  void dispatch(const KernelDef& kernel, std::initializer_list<Arg> args, const Push& push,
                Groups groups, std::initializer_list<std::uint32_t> spec = {}) {
    static_assert(std::is_trivially_copyable_v<Push>, "push constants must be trivially copyable");
    static_assert(sizeof(Push) <= 128, "push constants are limited to 128 bytes");
    dispatch_raw(kernel, args, &push, sizeof(Push), groups, spec);
  }
  void dispatch(const KernelDef& kernel, std::initializer_list<Arg> args, Groups groups,
                std::initializer_list<std::uint32_t> spec = {}) {
    dispatch_raw(kernel, args, nullptr, 0, groups, spec);
  }
  void dispatch_raw(const KernelDef& kernel, std::initializer_list<Arg> args, const void* push,
                    std::uint32_t push_bytes, Groups groups,
                    std::initializer_list<std::uint32_t> spec);

  // Transfer commands (vkCmdCopyBuffer / vkCmdFillBuffer).
  void copy(const Tensor& src, const Tensor& dst);
  void fill(const Tensor& dst, std::uint32_t bits);  // every 32-bit word = bits
  void fill(const Tensor& dst, float value);

  // Keeps `t`'s memory alive until the recorded work has finished.
  void keep_alive(const Tensor& t);

  void submit();  // asynchronous; the stream's fence signals completion
  // submit() that also waits for / signals the host's semaphores and signals
  // its fence. With nothing recorded it submits just the semaphore and fence
  // operations (e.g. "signal S once everything before has finished").
  // Not for streams on HostCommands (the host submits those itself).
  void submit(const SubmitSync& sync);
  void wait();  // waits for the submitted work; the stream can record again
  void run() {
    submit();
    wait();
  }

  bool recording() const;          // has unsubmitted commands
  bool host_commands() const;      // records into a HostCommands' buffers
  std::size_t dispatches() const;  // recorded since the last wait
  std::size_t barriers() const;    // inserted since the last wait
  const Device& device() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace vkjr2
