// vkjr2 error policy: every failure is a vkjr2::Error that says what failed,
// the input at fault, and what to do about it. Destructors never throw.
#pragma once

#include <vulkan/vulkan.h>

#include <cstdint>
#include <stdexcept>
#include <string>
#include <string_view>

namespace vkjr2 {

class Error : public std::runtime_error {
 public:
  // op: what was being done ("Tensor::empty", "dispatch axpy");
  // problem: what went wrong, naming the input at fault;
  // fix: what the user can do about it.
  Error(std::string op, std::string problem, std::string fix, VkResult result = VK_SUCCESS);

  const std::string& op() const noexcept { return op_; }
  const std::string& problem() const noexcept { return problem_; }
  const std::string& fix() const noexcept { return fix_; }
  VkResult result() const noexcept { return result_; }

 private:
  std::string op_;
  std::string problem_;
  std::string fix_;
  VkResult result_;
};

// No usable Vulkan driver or device.
class NoDeviceError : public Error {
 public:
  using Error::Error;
};

// A device memory allocation could not be satisfied.
class OutOfMemoryError : public Error {
 public:
  OutOfMemoryError(std::string op, std::uint64_t requested_bytes, std::uint64_t free_bytes,
                   std::string problem, std::string fix, VkResult result);
  std::uint64_t requested_bytes() const noexcept { return requested_; }
  std::uint64_t free_bytes() const noexcept { return free_; }

 private:
  std::uint64_t requested_;
  std::uint64_t free_;
};

// A caller passed something the op cannot work with (shape, size, value).
class InvalidArgument : public Error {
 public:
  InvalidArgument(std::string op, std::string problem, std::string fix = {});
};

// "VK_ERROR_OUT_OF_DEVICE_MEMORY" etc.
std::string_view vk_result_name(VkResult result) noexcept;

// Throws an Error naming op and the VkResult when result is not VK_SUCCESS,
// with a fix suited to the result code.
void check(VkResult result, std::string_view op);

// "1.50 GiB", "12.0 MiB", "512 B".
std::string format_bytes(std::uint64_t bytes);

}  // namespace vkjr2
