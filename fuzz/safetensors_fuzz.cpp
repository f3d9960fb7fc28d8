// libFuzzer target: parse_safetensors on arbitrary bytes. A vkjr2::Error is
// the expected answer to bad input; any other exception, a crash, a sanitizer
// report, a leak or an allocation above -malloc_limit_mb is a finding.
#include <vkjr2/nets/safetensors.hpp>

#include <cstddef>
#include <cstdint>
#include <span>

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  try {
    const auto file =
        vkjr2::nets::parse_safetensors(std::span(reinterpret_cast<const std::byte*>(data), size));
    // Exercise the conversions on whatever parsed.
    for (const auto& t : file.tensors) {
      if (t.to_float().size() != std::size_t(t.numel())) __builtin_trap();
    }
    // What parses must re-serialize and parse back to the same tensors.
    const auto again = vkjr2::nets::parse_safetensors(
        vkjr2::nets::serialize_safetensors(file.tensors, file.metadata));
    if (again.tensors.size() != file.tensors.size() || again.metadata != file.metadata) {
      __builtin_trap();
    }
    for (const auto& t : file.tensors) {
      const auto* u = again.find(t.name);
      if (!u || u->data != t.data || u->shape != t.shape || u->dtype != t.dtype) __builtin_trap();
    }
  } catch (const vkjr2::Error&) {
  }
  return 0;
}
