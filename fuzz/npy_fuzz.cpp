// libFuzzer target: parse_npy on arbitrary bytes. A vkjr2::Error is the
// expected answer to bad input; anything else is a finding.
#include <vkjr2/runtime/npy.hpp>

#include <cstddef>
#include <cstdint>
#include <span>

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  try {
    const auto t = vkjr2::parse_npy(std::span(reinterpret_cast<const std::byte*>(data), size));
    if (std::int64_t(t.values.size()) != t.numel()) __builtin_trap();
    // What parses must round-trip through the writer (bit patterns compared,
    // so NaNs count as equal).
    const auto back = vkjr2::parse_npy(vkjr2::serialize_npy(t));
    if (back.shape != t.shape || back.values.size() != t.values.size()) __builtin_trap();
    for (std::size_t i = 0; i < t.values.size(); ++i) {
      if (__builtin_memcmp(&back.values[i], &t.values[i], sizeof(float)) != 0) __builtin_trap();
    }
  } catch (const vkjr2::Error&) {
  }
  return 0;
}
