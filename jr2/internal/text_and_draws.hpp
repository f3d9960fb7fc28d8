// What jr2/'s files share (internal): random draws that are the same on
// every platform, and CSV fields.
#pragma once

#include <cstdint>
#include <cstdio>
#include <string>

namespace vkjr2::jr2::detail {

inline constexpr std::uint64_t kGoldenGamma = 0x9e3779b97f4a7c15ULL;

// SplitMix64's output function (Steele, Lea, Flood 2014): a well-mixed
// 64-bit value from any state; SplitMix64 itself is splitmix_finalize(state
// += kGoldenGamma).
constexpr std::uint64_t splitmix_finalize(std::uint64_t z) {
  z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ULL;
  z = (z ^ (z >> 27)) * 0x94d049bb133111ebULL;
  return z ^ (z >> 31);
}

// Uniform [0, 1) from the top 53 bits (std::uniform_real_distribution is
// not bit-exact across standard libraries).
constexpr double unit_interval(std::uint64_t bits) { return double(bits >> 11) * 0x1.0p-53; }

// A draw in [0, n) from `next()`, a source of uniform 64-bit values, without
// modulo bias (std::uniform_int_distribution differs between libraries).
template <class Next>
std::uint64_t draw_below(Next&& next, std::uint64_t n) {
  const std::uint64_t limit = ~0ULL - ~0ULL % n;
  std::uint64_t r = next();
  while (r >= limit) r = next();
  return r % n;
}

// A number as text with `digits` significant digits (printf's %.*g): 17
// round-trips a double exactly, 9 a float.
inline std::string number_text(double x, int digits) {
  char b[48];
  std::snprintf(b, sizeof b, "%.*g", digits, x);
  return b;
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
