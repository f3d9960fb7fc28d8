// Tensor: a typed, shaped range of device memory (up to 4-D, NCHW).
#pragma once

#include <vkjr2/runtime/device.hpp>

#include <vulkan/vulkan.h>

#include <array>
#include <cstdint>
#include <initializer_list>
#include <memory>
#include <span>
#include <string>
#include <vector>

namespace vkjr2 {

enum class DType : std::uint8_t { f32, f16, i32, u32 };
std::size_t dtype_size(DType dtype) noexcept;
const char* dtype_name(DType dtype) noexcept;

class Shape {
 public:
  static constexpr int kMaxRank = 4;
  Shape() = default;
  Shape(std::initializer_list<std::int64_t> dims);
  explicit Shape(std::span<const std::int64_t> dims);

  int rank() const noexcept { return rank_; }
  std::int64_t operator[](int axis) const;  // negative axis counts from the end
  std::int64_t numel() const noexcept;
  std::span<const std::int64_t> dims() const noexcept { return {dims_.data(), size_t(rank_)}; }
  std::string str() const;  // "[2, 3, 64, 64]"
  bool operator==(const Shape& other) const noexcept;

 private:
  std::array<std::int64_t, kMaxRank> dims_{};
  int rank_ = 0;
};

namespace detail {
struct Storage;
}

class Tensor {
 public:
  Tensor() = default;

  // Uninitialized device memory.
  static Tensor empty(const Device& device, const Shape& shape, DType dtype = DType::f32);
  // Device memory holding `values` (numel must match).
  static Tensor from(const Device& device, const Shape& shape, std::span<const float> values);
  // A buffer the host application owns (usage must include STORAGE_BUFFER and
  // TRANSFER_SRC/DST). vkjr2 never frees it; the host keeps it alive.
  static Tensor wrap(const Device& device, VkBuffer buffer, VkDeviceSize offset_bytes,
                     const Shape& shape, DType dtype = DType::f32);

  bool defined() const noexcept { return storage_ != nullptr; }
  const Shape& shape() const noexcept { return shape_; }
  DType dtype() const noexcept { return dtype_; }
  std::int64_t numel() const noexcept { return shape_.numel(); }
  std::uint64_t bytes() const noexcept { return std::uint64_t(numel()) * dtype_size(dtype_); }
  Device device() const;

  VkBuffer vk_buffer() const noexcept;
  VkDeviceSize vk_offset() const noexcept;  // bytes from the start of vk_buffer()

  // Host pointer to the tensor's memory where the device maps it directly
  // (unified memory); null elsewhere. Wait for streams using it first.
  void* mapped() const noexcept;

  // Synchronous copies between host and device (direct on unified memory,
  // through a staging buffer elsewhere). Sizes must match bytes().
  void upload(std::span<const float> values) const;
  void upload_bytes(const void* data, std::size_t size) const;
  std::vector<float> download() const;
  void download(std::span<float> out) const;
  void download_bytes(void* data, std::size_t size) const;

  // Same memory, another shape (numel must match).
  Tensor reshape(const Shape& shape) const;
  // A contiguous sub-range starting offset_elements in, with `shape`.
  Tensor view(const Shape& shape, std::int64_t offset_elements = 0) const;

  // A uniform texel buffer view of this tensor, cached with the storage.
  VkBufferView texel_view(VkFormat format) const;
  // Keeps the memory alive (streams hold this until their work finished).
  const std::shared_ptr<detail::Storage>& storage() const noexcept { return storage_; }

 private:
  Tensor(std::shared_ptr<detail::Storage> storage, VkDeviceSize offset, Shape shape, DType dtype);
  void check_host_size(std::size_t size, const char* op) const;

  std::shared_ptr<detail::Storage> storage_;
  VkDeviceSize offset_ = 0;  // bytes from the start of the storage
  Shape shape_;
  DType dtype_ = DType::f32;
};

}  // namespace vkjr2
