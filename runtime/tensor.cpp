#include <vkjr2/runtime/tensor.hpp>

#include <cstring>
#include <mutex>
#include <string>

#include "internal/device_core.hpp"

namespace vkjr2 {

std::size_t dtype_size(DType dtype) noexcept {
  switch (dtype) {
    case DType::f16:
      return 2;
    case DType::f32:
    case DType::i32:
    case DType::u32:
      return 4;
  }
  return 4;
}

const char* dtype_name(DType dtype) noexcept {
  switch (dtype) {
    case DType::f32:
      return "f32";
    case DType::f16:
      return "f16";
    case DType::i32:
      return "i32";
    case DType::u32:
      return "u32";
  }
  return "?";
}

Shape::Shape(std::initializer_list<std::int64_t> dims)
    : Shape(std::span<const std::int64_t>(dims.begin(), dims.size())) {}

Shape::Shape(std::span<const std::int64_t> dims) {
  if (dims.size() > kMaxRank) {
    throw InvalidArgument("Shape", "rank " + std::to_string(dims.size()) + " exceeds 4",
                          "fold leading dimensions into the batch (N) axis");
  }
  for (std::size_t i = 0; i < dims.size(); ++i) {
    if (dims[i] < 0) {
      throw InvalidArgument("Shape", "dimension " + std::to_string(i) + " is negative (" +
                                         std::to_string(dims[i]) + ")");
    }
    dims_[i] = dims[i];
  }
  rank_ = static_cast<int>(dims.size());
}

std::int64_t Shape::operator[](int axis) const {
  const int a = axis < 0 ? axis + rank_ : axis;
  if (a < 0 || a >= rank_) {
    throw InvalidArgument("Shape", "axis " + std::to_string(axis) + " out of range for " + str());
  }
  return dims_[a];
}

std::int64_t Shape::numel() const noexcept {
  std::int64_t n = 1;
  for (int i = 0; i < rank_; ++i) n *= dims_[i];
  return n;
}

std::string Shape::str() const {
  std::string s = "[";
  for (int i = 0; i < rank_; ++i) s += (i ? ", " : "") + std::to_string(dims_[i]);
  return s + "]";
}

bool Shape::operator==(const Shape& other) const noexcept {
  if (rank_ != other.rank_) return false;
  for (int i = 0; i < rank_; ++i) {
    if (dims_[i] != other.dims_[i]) return false;
  }
  return true;
}

Tensor::Tensor(std::shared_ptr<detail::Storage> storage, VkDeviceSize offset, Shape shape,
               DType dtype)
    : storage_(std::move(storage)), offset_(offset), shape_(shape), dtype_(dtype) {}

Tensor Tensor::empty(const Device& device, const Shape& shape, DType dtype) {
  auto storage = std::make_shared<detail::Storage>();
  storage->core = device.shared_core();
  const VkDeviceSize bytes = VkDeviceSize(shape.numel()) * dtype_size(dtype);
  if (bytes > 0) {
    storage->allocation = storage->core->allocator->allocate(
        bytes, "allocate tensor " + shape.str() + " " + dtype_name(dtype));
    storage->buffer = storage->allocation.block->buffer;
    storage->base = storage->allocation.offset;
    storage->size = bytes;
    if (storage->allocation.block->mapped != nullptr && !storage->core->staging) {
      storage->mapped = storage->allocation.block->mapped + storage->allocation.offset;
    }
  }
  return Tensor(std::move(storage), 0, shape, dtype);
}

Tensor Tensor::from(const Device& device, const Shape& shape, std::span<const float> values) {
  Tensor t = empty(device, shape, DType::f32);
  t.upload(values);
  return t;
}

Tensor Tensor::wrap(const Device& device, VkBuffer buffer, VkDeviceSize offset_bytes,
                    const Shape& shape, DType dtype) {
  if (buffer == VK_NULL_HANDLE) {
    throw InvalidArgument("Tensor::wrap", "the host buffer is VK_NULL_HANDLE");
  }
  auto storage = std::make_shared<detail::Storage>();
  storage->core = device.shared_core();
  storage->buffer = buffer;
  storage->base = offset_bytes;
  storage->size = VkDeviceSize(shape.numel()) * dtype_size(dtype);
  return Tensor(std::move(storage), 0, shape, dtype);
}

Device Tensor::device() const {
  if (!storage_) throw InvalidArgument("Tensor::device", "the tensor is undefined");
  return Device(storage_->core);
}

VkBuffer Tensor::vk_buffer() const noexcept { return storage_ ? storage_->buffer : VK_NULL_HANDLE; }
VkDeviceSize Tensor::vk_offset() const noexcept { return storage_ ? storage_->base + offset_ : 0; }

void* Tensor::mapped() const noexcept {
  return (storage_ && storage_->mapped) ? storage_->mapped + offset_ : nullptr;
}

void Tensor::check_host_size(std::size_t size, const char* op) const {
  if (!storage_) throw InvalidArgument(op, "the tensor is undefined");
  if (size != bytes()) {
    throw InvalidArgument(op,
                          "host data has " + std::to_string(size) + " bytes but tensor " +
                              shape_.str() + " " + dtype_name(dtype_) + " has " +
                              std::to_string(bytes()),
                          "pass exactly numel() values");
  }
}

void Tensor::upload(std::span<const float> values) const {
  if (dtype_ != DType::f32) {
    throw InvalidArgument(
        "Tensor::upload",
        std::string("tensor is ") + dtype_name(dtype_) + ", float values need f32",
        "use upload_bytes");
  }
  upload_bytes(values.data(), values.size_bytes());
}

void Tensor::upload_bytes(const void* data, std::size_t size) const {
  check_host_size(size, "Tensor::upload");
  if (size == 0) return;
  if (void* dst = mapped()) {
    std::memcpy(dst, data, size);
  } else {
    storage_->core->copy_host_to_buffer(data, vk_buffer(), vk_offset(), size);
  }
}

std::vector<float> Tensor::download() const {
  std::vector<float> out(static_cast<std::size_t>(numel()));
  download(out);
  return out;
}

void Tensor::download(std::span<float> out) const {
  if (dtype_ != DType::f32) {
    throw InvalidArgument(
        "Tensor::download",
        std::string("tensor is ") + dtype_name(dtype_) + ", float values need f32",
        "use download_bytes");
  }
  download_bytes(out.data(), out.size_bytes());
}

void Tensor::download_bytes(void* data, std::size_t size) const {
  check_host_size(size, "Tensor::download");
  if (size == 0) return;
  if (const void* src = mapped()) {
    std::memcpy(data, src, size);
  } else {
    storage_->core->copy_buffer_to_host(vk_buffer(), vk_offset(), data, size);
  }
}

Tensor Tensor::reshape(const Shape& shape) const {
  if (shape.numel() != numel()) {
    throw InvalidArgument("Tensor::reshape", "cannot reshape " + shape_.str() + " (" +
                                                 std::to_string(numel()) + " elements) to " +
                                                 shape.str());
  }
  return Tensor(storage_, offset_, shape, dtype_);
}

Tensor Tensor::view(const Shape& shape, std::int64_t offset_elements) const {
  if (offset_elements < 0 || offset_elements + shape.numel() > numel()) {
    throw InvalidArgument("Tensor::view", "view " + shape.str() + " at element " +
                                              std::to_string(offset_elements) +
                                              " does not fit in " + shape_.str());
  }
  return Tensor(storage_, offset_ + VkDeviceSize(offset_elements) * dtype_size(dtype_), shape,
                dtype_);
}

VkBufferView Tensor::texel_view(VkFormat format) const {
  if (!storage_) throw InvalidArgument("Tensor::texel_view", "the tensor is undefined");
  const VkDeviceSize offset = vk_offset();
  const VkDeviceSize range = bytes();
  std::lock_guard lock(storage_->views_mutex);
  for (const auto& v : storage_->views) {
    if (v.format == format && v.offset == offset && v.range == range) return v.view;
  }
  VkBufferViewCreateInfo info{VK_STRUCTURE_TYPE_BUFFER_VIEW_CREATE_INFO};
  info.buffer = vk_buffer();
  info.format = format;
  info.offset = offset;
  info.range = range;
  VkBufferView view = VK_NULL_HANDLE;
  check(vkCreateBufferView(storage_->core->device, &info, nullptr, &view),
        "create texel buffer view");
  storage_->views.push_back({format, offset, range, view});
  return view;
}

}  // namespace vkjr2
