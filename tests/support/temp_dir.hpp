// A fresh temporary folder per test, removed at the end.
#pragma once

#include <gtest/gtest.h>
#include <unistd.h>

#include <filesystem>
#include <string>

namespace vkjr2::test {

struct TempDir {
  std::filesystem::path path;
  // Named after the running test (and the process, so parallel runs of one
  // test binary do not collide).
  TempDir() : TempDir(::testing::UnitTest::GetInstance()->current_test_info()->name()) {}
  explicit TempDir(const std::string& tag)
      : path(std::filesystem::temp_directory_path() /
             ("vkjr2_" + tag + "_" + std::to_string(::getpid()))) {
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

}  // namespace vkjr2::test
