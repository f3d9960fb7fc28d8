// Files for command-runner tests: a fresh temporary folder per test
// (support/temp_dir.hpp) and the JSON a command printed.
#pragma once

#include <nlohmann/json.hpp>

#include <filesystem>
#include <fstream>
#include <iterator>
#include <string>

#include "support/temp_dir.hpp"

namespace vkjr2::test {

// The first JSON value in a command's output (null when there is none);
// the command's own message lines ("vkjr2: warning: ...") are skipped.
inline nlohmann::json parse_json(const std::string& out) {
  std::string text;
  std::size_t at = 0;
  while (at < out.size()) {
    std::size_t end = out.find('\n', at);
    end = end == std::string::npos ? out.size() : end + 1;
    if (out.compare(at, 7, "vkjr2: ") != 0) text.append(out, at, end - at);
    at = end;
  }
  const auto start = text.find_first_of("[{");
  if (start == std::string::npos) return nlohmann::json();
  return nlohmann::json::parse(text.substr(start), nullptr, false);
}

// A file's bytes (empty when it cannot be read).
inline std::string read_bytes(const std::filesystem::path& path) {
  std::ifstream in(path, std::ios::binary);
  return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}

}  // namespace vkjr2::test
