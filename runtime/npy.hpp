// NumPy .npy arrays (format versions 1.0, 2.0 and 3.0): magic "\x93NUMPY",
// major/minor version, header length (u16 for v1, u32 for v2/3), a Python dict
// literal {'descr': '<f4', 'fortran_order': False, 'shape': (h, w, c), }
// padded with spaces and a newline to 64-byte alignment, then the data.
// Used for images handed to the CLI (float32 HWC RGB in 0..255) and for test
// references.
#pragma once

#include <vkjr2/runtime/host_tensor.hpp>

#include <cstddef>
#include <filesystem>
#include <span>
#include <string_view>

namespace vkjr2 {

// Reads '<f4', '<f8', '|u1' (also '<u1'), '<i4' arrays of any rank >= 0 in C
// order and converts them to float32. Throws InvalidArgument naming the file
// for a bad magic or version, a header longer than the file, a malformed
// header dict, big-endian or unsupported dtypes, Fortran order, or a data size
// that does not match the shape.
HostTensor read_npy(const std::filesystem::path& path);
// Same on bytes in memory; `source` names them in errors.
HostTensor parse_npy(std::span<const std::byte> bytes, std::string_view source = "<memory>");

// The exact bytes write_npy stores: version 1.0 ('<f4', C order; 2.0 if the
// header does not fit 64 KiB), header padded to a multiple of 64 bytes.
std::vector<std::byte> serialize_npy(const HostTensor& tensor);
// Writes float32 atomically (temporary file in the same directory + rename).
// Throws InvalidArgument if values.size() does not match the shape.
void write_npy(const std::filesystem::path& path, const HostTensor& tensor);

}  // namespace vkjr2
