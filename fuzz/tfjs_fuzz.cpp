// libFuzzer target: parse_tfjs_weights. Input framing (also used by the seed
// corpus, see make_corpus.cpp):
//   u16 LE manifest length M, M bytes of manifest JSON, then zero or more
//   groups, each a u32 LE length L (clipped to what is left) and L bytes.
// A vkjr2::Error is the expected answer to bad input; anything else is a
// finding.
#include <vkjr2/nets/tfjs_weights.hpp>

#include <cstddef>
#include <cstdint>
#include <span>
#include <string_view>
#include <vector>

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  if (size < 2) return 0;
  std::size_t manifest_len = std::size_t(data[0]) | (std::size_t(data[1]) << 8);
  std::size_t pos = 2;
  if (manifest_len > size - pos) manifest_len = size - pos;
  const std::string_view manifest(reinterpret_cast<const char*>(data + pos), manifest_len);
  pos += manifest_len;
  std::vector<std::span<const std::byte>> groups;
  while (size - pos >= 4) {
    std::size_t len = std::size_t(data[pos]) | (std::size_t(data[pos + 1]) << 8) |
                      (std::size_t(data[pos + 2]) << 16) | (std::size_t(data[pos + 3]) << 24);
    pos += 4;
    if (len > size - pos) len = size - pos;
    groups.emplace_back(reinterpret_cast<const std::byte*>(data + pos), len);
    pos += len;
  }
  try {
    const auto w = vkjr2::nets::parse_tfjs_weights(manifest, groups);
    for (const auto& [name, t] : w.entries()) {
      if (std::int64_t(t.values.size()) != t.numel() || &w.at(name) != &t) __builtin_trap();
    }
    (void)w.parameter_count();
  } catch (const vkjr2::Error&) {
  }
  return 0;
}
