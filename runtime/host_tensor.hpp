// HostTensor: a float32 array in host memory (row-major), the common currency
// of the weight and array loaders (safetensors, TF.js, .npy). Plus the file
// helpers those loaders share: whole-file reads and atomic writes.
#pragma once

#include <vkjr2/runtime/error.hpp>
#include <vkjr2/runtime/tensor.hpp>

#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <span>
#include <string>
#include <string_view>
#include <vector>

namespace vkjr2 {

struct HostTensor {
  std::vector<std::int64_t> shape;  // any rank >= 0; rank 0 holds one value
  std::vector<float> values;        // row-major, values.size() == numel()

  // Product of shape (1 for rank 0). Throws InvalidArgument on a negative
  // dimension or an int64 overflow.
  std::int64_t numel() const;
};

// "[2, 3, 64]"; "[]" for rank 0.
std::string shape_str(std::span<const std::int64_t> shape);

// Product of dims with every step checked: throws InvalidArgument (naming
// `what`) on a negative dimension or a product above max_numel.
std::int64_t checked_numel(std::span<const std::int64_t> dims, std::string_view what,
                           std::int64_t max_numel = INT64_MAX);

// The whole file as bytes; throws Error naming the path when it cannot be read.
std::vector<std::byte> read_file_bytes(const std::filesystem::path& path, std::string_view op);

// Writes bytes to `path` atomically: a temporary file in the same directory,
// flushed and synced, then renamed over `path`. On any failure the temporary
// is removed, `path` is untouched, and an Error naming the path is thrown.
void write_file_atomic(const std::filesystem::path& path, std::span<const std::byte> bytes,
                       std::string_view op);

// Uploads to a device Tensor (Shape is at most 4-D). Header-only so that code
// using just the loaders does not link the Vulkan runtime.
inline Tensor to_device(const Device& device, const HostTensor& host, std::string_view name = {}) {
  const std::string what =
      name.empty() ? std::string("host tensor") : "'" + std::string(name) + "'";
  if (host.shape.size() > std::size_t(Shape::kMaxRank)) {
    throw InvalidArgument("to_device",
                          what + " has rank " + std::to_string(host.shape.size()) + " (shape " +
                              shape_str(host.shape) + "), device tensors hold at most " +
                              std::to_string(Shape::kMaxRank) + " dimensions",
                          "reshape it on the host (merge leading dimensions) before uploading");
  }
  if (std::int64_t(host.values.size()) != host.numel()) {
    throw InvalidArgument("to_device",
                          what + " holds " + std::to_string(host.values.size()) +
                              " values but its shape " + shape_str(host.shape) + " needs " +
                              std::to_string(host.numel()),
                          "make values.size() equal the product of shape");
  }
  const Shape shape =
      host.shape.empty() ? Shape{1} : Shape(std::span<const std::int64_t>(host.shape));
  return Tensor::from(device, shape, host.values);
}

}  // namespace vkjr2
