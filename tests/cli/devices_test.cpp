// The vkjr2 binary, run as a user would.
#include <gtest/gtest.h>

#include <string>

#include "support/run_cli.hpp"

namespace {

using Result = vkjr2::test::CliResult;

Result run(const std::string& args, const std::string& env = "") {
  return vkjr2::test::run_cli(args, env);
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
  EXPECT_NE(r.output.find("tuning          lavapipe (measured"), std::string::npos) << r.output;
}

TEST(Cli, DevicesTuningFollowsTheOverride) {
  const Result gpu = run("devices --json", "VKJR2_DEVICE_TRAITS=gpu");
  EXPECT_EQ(gpu.code, 0) << gpu.output;
  EXPECT_NE(gpu.output.find("\"tuning\": \"gpu\""), std::string::npos) << gpu.output;
  const Result bad = run("devices", "VKJR2_DEVICE_TRAITS=fast");
  EXPECT_NE(bad.code, 0) << bad.output;
  EXPECT_NE(bad.output.find("VKJR2_DEVICE_TRAITS"), std::string::npos) << bad.output;
  EXPECT_NE(bad.output.find("'lavapipe' or 'gpu'"), std::string::npos) << bad.output;
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
