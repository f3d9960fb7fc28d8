// Where the face-api references live (written by scripts/setup with
// tests/parity/face_api_reference.mjs) and how tests read them. A test that
// needs them fails, naming the fix, when they are missing.
#pragma once

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <cstdlib>
#include <filesystem>
#include <fstream>

namespace vkjr2::test {

// $VKJR2_PARITY_DIR, else ${VKJR2_CACHE_DIR:-$HOME/.cache/vkjr2}/parity.
inline std::filesystem::path parity_dir() {
  if (const char* p = std::getenv("VKJR2_PARITY_DIR"); p != nullptr && *p != 0) return p;
  std::filesystem::path cache;
  if (const char* c = std::getenv("VKJR2_CACHE_DIR"); c != nullptr && *c != 0) {
    cache = c;
  } else if (const char* home = std::getenv("HOME"); home != nullptr && *home != 0) {
    cache = std::filesystem::path(home) / ".cache" / "vkjr2";
  }
  return cache / "parity";
}

// index.json; an empty object (and a test failure) when it is missing.
inline nlohmann::json parity_index() {
  const auto path = parity_dir() / "index.json";
  std::ifstream in(path);
  if (!in) {
    ADD_FAILURE() << "face-api references missing at " << path.string()
                  << ": run scripts/setup (it generates them with Node + TF.js)";
    return nlohmann::json::object();
  }
  return nlohmann::json::parse(in);
}

}  // namespace vkjr2::test
