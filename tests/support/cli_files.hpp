// Files for command-runner tests: a fresh temporary folder per test and the
// JSON a command printed.
#pragma once

#include <nlohmann/json.hpp>
#include <unistd.h>

#include <filesystem>
#include <string>

namespace vkjr2::test {

// A fresh folder per test, removed at the end.
struct TempDir {
  std::filesystem::path path;
  explicit TempDir(const std::string& tag)
      : path(std::filesystem::temp_directory_path() /
             ("vkjr2_cli_" + tag + "_" + std::to_string(::getpid()))) {
    std::filesystem::remove_all(path);
    std::filesystem::create_directories(path);
  }
  ~TempDir() {
    std::error_code ec;
    std::filesystem::remove_all(path, ec);
  }
  TempDir(const TempDir&) = delete;
  TempDir& operator=(const TempDir&) = delete;
};

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

}  // namespace vkjr2::test
