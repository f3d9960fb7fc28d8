// Runs the vkjr2 binary as a user would (stdout and stderr together).
#pragma once

#include <sys/wait.h>

#include <array>
#include <cstdio>
#include <string>

namespace vkjr2::test {

struct CliResult {
  int code = -1;
  std::string output;
};

// Under AddressSanitizer the command runs with a 32 MiB quarantine of freed
// memory instead of 256 MiB: lavapipe frees large buffers by the gigabyte in
// a command that makes a benchmark, and the default held 9 GB and ran 2.5×
// slower (measured on `vkjr2 dataset make`).
#if defined(__SANITIZE_ADDRESS__)
inline constexpr const char* kCliSanitizerEnv =
    "ASAN_OPTIONS=\"${ASAN_OPTIONS}:quarantine_size_mb=32\" ";
#else
inline constexpr const char* kCliSanitizerEnv = "";
#endif

inline CliResult run_cli(const std::string& args, const std::string& env = "") {
  const std::string cmd = std::string(kCliSanitizerEnv) + env + " " + std::string(VKJR2_CLI_PATH) +
                          " " + args + " 2>&1";
  CliResult r;
  FILE* pipe = popen(cmd.c_str(), "r");
  if (pipe == nullptr) return r;
  std::array<char, 4096> buf{};
  while (fgets(buf.data(), int(buf.size()), pipe) != nullptr) r.output += buf.data();
  const int status = pclose(pipe);
  r.code = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
  return r;
}

}  // namespace vkjr2::test
