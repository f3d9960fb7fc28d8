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

inline CliResult run_cli(const std::string& args, const std::string& env = "") {
  const std::string cmd = env + " " + std::string(VKJR2_CLI_PATH) + " " + args + " 2>&1";
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
