// What the evaluation's files share (internal to jr2/): unbiased bounded
// random draws that are the same on every platform, and CSV fields.
#pragma once

#include <cstdint>
#include <string>

namespace vkjr2::jr2::detail {

// A draw in [0, n) from `next()`, a source of uniform 64-bit values, without
// modulo bias (std::uniform_int_distribution differs between libraries).
template <class Next>
std::uint64_t draw_below(Next&& next, std::uint64_t n) {
  const std::uint64_t limit = ~0ULL - ~0ULL % n;
  std::uint64_t r = next();
  while (r >= limit) r = next();
  return r % n;
}

// A CSV field: quoted (inner quotes doubled) when it holds a comma, a quote
// or a newline (RFC 4180).
inline std::string csv_field(const std::string& s) {
  if (s.find_first_of(",\"\n") == std::string::npos) return s;
  std::string q = "\"";
  for (char c : s) q += c == '"' ? std::string("\"\"") : std::string(1, c);
  return q + "\"";
}

}  // namespace vkjr2::jr2::detail
