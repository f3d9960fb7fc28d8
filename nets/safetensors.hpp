// safetensors (https://github.com/huggingface/safetensors, format as written by
// its reference implementation): 8-byte little-endian header length N, N bytes
// of JSON {name: {"dtype", "shape", "data_offsets": [begin, end]}, optional
// "__metadata__": {str: str}} padded with spaces to a multiple of 8, then the
// byte buffer. Offsets are relative to the buffer start; the tensors cover the
// buffer exactly, without holes or overlaps. Used for checkpoints (weights and
// optimizer state) and the project's own trained artifacts.
#pragma once

#include <vkjr2/runtime/host_tensor.hpp>

#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <map>
#include <optional>
#include <span>
#include <string>
#include <string_view>
#include <vector>

namespace vkjr2::nets {

enum class StDType : std::uint8_t {
  BOOL,
  U8,
  I8,
  I16,
  U16,
  F16,
  BF16,
  I32,
  U32,
  F32,
  I64,
  U64,
  F64
};

// Bytes per element (1, 2, 4 or 8).
std::size_t st_dtype_size(StDType dtype) noexcept;
// "F32", "BF16", ... (the spelling in the header).
const char* st_dtype_name(StDType dtype) noexcept;
// Parses a header dtype name; nullopt for names we do not support (F8_*, ...).
std::optional<StDType> st_dtype_from_name(std::string_view name) noexcept;

// One tensor: its dtype, shape and raw little-endian bytes (row-major).
struct SafetensorsRecord {
  std::string name;
  StDType dtype = StDType::F32;
  std::vector<std::int64_t> shape;
  std::vector<std::byte> data;  // numel() * st_dtype_size(dtype) bytes

  std::int64_t numel() const;
  // Every value converted to float (F16/BF16 exact, F64/I64/U64/I32/U32 rounded
  // to nearest float, BOOL to 0/1).
  std::vector<float> to_float() const;
  HostTensor to_host() const;  // {shape, to_float()}
  // Raw integer views; throw InvalidArgument naming the tensor if the dtype
  // differs (no silent conversion: optimizer counters must stay bit-exact).
  std::vector<std::int32_t> as_i32() const;
  std::vector<std::uint32_t> as_u32() const;

  static SafetensorsRecord f32(std::string name, std::vector<std::int64_t> shape,
                               std::span<const float> values);
  static SafetensorsRecord i32(std::string name, std::vector<std::int64_t> shape,
                               std::span<const std::int32_t> values);
  static SafetensorsRecord u32(std::string name, std::vector<std::int64_t> shape,
                               std::span<const std::uint32_t> values);
};

struct SafetensorsFile {
  std::vector<SafetensorsRecord> tensors;  // in buffer order (ascending offsets)
  std::map<std::string, std::string> metadata;

  // Null when absent.
  const SafetensorsRecord* find(std::string_view name) const noexcept;
  // Throws InvalidArgument naming the tensor and listing the names present.
  const SafetensorsRecord& at(std::string_view name) const;
};

// Reads and validates a whole file. Errors (vkjr2::Error / InvalidArgument)
// name the file and the tensor and say what is wrong.
SafetensorsFile read_safetensors(const std::filesystem::path& path);
// Same on bytes in memory; `source` names them in errors.
SafetensorsFile parse_safetensors(std::span<const std::byte> bytes,
                                  std::string_view source = "<memory>");

// The exact bytes write_safetensors stores (header padded to a multiple of 8,
// tensors sorted by dtype size descending, then name, as the reference writer
// does so that every tensor is aligned to its element size).
std::vector<std::byte> serialize_safetensors(
    std::span<const SafetensorsRecord> records,
    const std::map<std::string, std::string>& metadata = {});
// Writes atomically (temporary file in the same directory + rename). Throws
// InvalidArgument on duplicate or empty names, "__metadata__" as a tensor name,
// or data whose size does not match dtype x shape; the target is then untouched.
void write_safetensors(const std::filesystem::path& path,
                       std::span<const SafetensorsRecord> records,
                       const std::map<std::string, std::string>& metadata = {});

// Float convenience: every tensor converted to float32 (any dtype).
std::map<std::string, HostTensor> read_safetensors_f32(const std::filesystem::path& path);
// Writes each HostTensor as F32.
void write_safetensors_f32(const std::filesystem::path& path,
                           const std::map<std::string, HostTensor>& tensors,
                           const std::map<std::string, std::string>& metadata = {});

}  // namespace vkjr2::nets
