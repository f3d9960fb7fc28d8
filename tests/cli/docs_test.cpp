// docs/cli.md is generated from the commands' --help (scripts/gen_cli_docs);
// this test fails when the two disagree, so the page cannot go stale.
#include <gtest/gtest.h>

#include <fstream>
#include <sstream>
#include <string>

#include "support/run_cli.hpp"

namespace {

std::string read_docs() {
  std::ifstream f(std::string(VKJR2_SOURCE_DIR) + "/docs/cli.md");
  std::stringstream ss;
  ss << f.rdbuf();
  return ss.str();
}

// --help as the page shows it: the binary's path replaced by "vkjr2".
std::string help(const std::string& command) {
  auto r = vkjr2::test::run_cli(command + " --help");
  EXPECT_EQ(r.code, 0) << command;
  const std::string path = VKJR2_CLI_PATH;
  for (std::size_t at = r.output.find(path); at != std::string::npos;
       at = r.output.find(path, at)) {
    r.output.replace(at, path.size(), "vkjr2");
  }
  return r.output;
}

TEST(CliDocs, EveryCommandsHelpIsInDocsCliMd) {
  const std::string docs = read_docs();
  ASSERT_FALSE(docs.empty()) << "docs/cli.md is missing";
  for (const char* c :
       {"",           "dataset",   "dataset make",    "dataset merge", "eval",      "gate",
        "gate train", "demo",      "demo-turbulence", "devices",       "detect",    "embed",
        "verify",     "identify",  "simulate",        "wave",          "sim-train", "sim-validate",
        "bench",      "bench sim", "bench kernels"}) {
    const std::string h = help(c);
    EXPECT_NE(h.find("Usage"), std::string::npos) << c;
    EXPECT_NE(docs.find("```\n" + h + "```"), std::string::npos)
        << "docs/cli.md is out of date for `vkjr2 " << c << " --help`: run scripts/gen_cli_docs";
  }
}

}  // namespace
