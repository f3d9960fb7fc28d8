// Stream: records many dispatches and copies into one command buffer,
// inserting the barriers that data hazards need, then submits them.
#pragma once

#include <vkjr2/runtime/kernel.hpp>

#include <cstdint>
#include <initializer_list>
#include <memory>
#include <type_traits>

namespace vkjr2 {

class Stream {
 public:
  explicit Stream(const Device& device);
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
  void wait();    // waits for the submitted work; the stream can record again
  void run() {
    submit();
    wait();
  }

  bool recording() const;          // has unsubmitted commands
  std::size_t dispatches() const;  // recorded since the last wait
  std::size_t barriers() const;    // inserted since the last wait
  const Device& device() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace vkjr2
