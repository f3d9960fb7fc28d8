// The vkjr2 binary, run as a user would.
#include <gtest/gtest.h>
#include <sys/wait.h>

#include <array>
#include <cstdio>
#include <string>

namespace {

struct Result {
  int code;
  std::string output;
};

Result run(const std::string& args, const std::string& env = "") {
  const std::string cmd = env + " " + std::string(VKJR2_CLI_PATH) + " " + args + " 2>&1";
  Result r{-1, {}};
  FILE* pipe = popen(cmd.c_str(), "r");
  if (!pipe) return r;
  std::array<char, 4096> buf{};
  while (fgets(buf.data(), int(buf.size()), pipe)) r.output += buf.data();
  const int status = pclose(pipe);
  r.code = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
  return r;
}

TEST(Cli, HelpListsCommandsAndEnvironment) {
  const Result r = run("--help");
  EXPECT_EQ(r.code, 0) << r.output;
  EXPECT_NE(r.output.find("devices"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("VKJR2_DEVICE"), std::string::npos) << r.output;
}

TEST(Cli, DevicesListsLavapipe) {
  const Result r = run("devices");
  EXPECT_EQ(r.code, 0) << r.output;
  EXPECT_NE(r.output.find("llvmpipe"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("subgroup size"), std::string::npos) << r.output;
}

TEST(Cli, DevicesJson) {
  const Result r = run("devices --json");
  EXPECT_EQ(r.code, 0) << r.output;
  EXPECT_EQ(r.output.front(), '[') << r.output;
  EXPECT_NE(r.output.find("\"subgroup_size\""), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("\"selected\": true"), std::string::npos) << r.output;
}

TEST(Cli, NoDriverExitsWithCode3AndHint) {
  const Result none = run("devices", "VK_ICD_FILENAMES=/nonexistent VK_DRIVER_FILES=/nonexistent");
  EXPECT_EQ(none.code, 3) << none.output;
  EXPECT_NE(none.output.find("mesa-vulkan-drivers"), std::string::npos) << none.output;
  EXPECT_EQ(none.output.find("terminate"), std::string::npos) << none.output;
}

TEST(Cli, UnknownCommandIsAUsageError) {
  const Result r = run("no-such-command");
  EXPECT_EQ(r.code, 2) << r.output;
  EXPECT_NE(r.output.find("no-such-command"), std::string::npos) << r.output;
}

}  // namespace
