// --config FILE for the training commands: a JSON or YAML map of a
// command's long option names (without the dashes) to values; lists for
// multi-value options. Options given on the command line win.
#pragma once

#include <CLI/CLI.hpp>
#include <yaml-cpp/yaml.h>

#include <sstream>
#include <string>
#include <vector>

#include "checks.hpp"

namespace vkjr2::cli {

class YamlConfig : public CLI::Config {
 public:
  std::string to_config(const CLI::App*, bool, bool, std::string) const override { return {}; }
  std::vector<CLI::ConfigItem> from_config(std::istream& in) const override {
    std::stringstream text;
    text << in.rdbuf();
    YAML::Node root;
    try {
      root = YAML::Load(text.str());
    } catch (const YAML::Exception& e) {
      throw CLI::ConversionError("--config: not JSON or YAML: " + std::string(e.what()));
    }
    std::vector<CLI::ConfigItem> out;
    if (root.IsNull()) return out;
    if (!root.IsMap()) throw CLI::ConversionError("--config: the file must hold a map of options");
    for (const auto& kv : root) {
      CLI::ConfigItem item;
      item.name = kv.first.as<std::string>();
      if (kv.second.IsSequence()) {
        for (const auto& v : kv.second) item.inputs.push_back(v.as<std::string>());
      } else if (kv.second.IsScalar()) {
        item.inputs.push_back(kv.second.as<std::string>());
      } else {
        throw CLI::ConversionError("--config: " + item.name + " must be a value or a list");
      }
      out.push_back(std::move(item));
    }
    return out;
  }
};

// Applies a --config file to `cmd`'s options that the command line did not
// set (CLI11 reads config files for the top-level app only): each item's
// values go through the option's validators and into its variable. Throws
// UsageError naming the file and the key that is not an option.
inline void apply_config_file(CLI::App* cmd, const std::string& path) {
  if (path.empty()) return;
  std::vector<CLI::ConfigItem> items;
  try {
    items = YamlConfig().from_file(path);
  } catch (const CLI::Error& e) {
    throw UsageError("--config", path + ": " + e.what(), "pass a JSON or YAML map of options");
  }
  for (const CLI::ConfigItem& item : items) {
    CLI::Option* op = cmd->get_option_no_throw("--" + item.name);
    if (op == nullptr || item.name == "config") {
      throw UsageError(
          "--config", path + ": '" + item.name + "' is not an option of " + cmd->get_name(),
          "use the long option names of `vkjr2 " + cmd->get_name() + " --help` without the dashes");
    }
    if (op->count() > 0) continue;  // the command line wins
    try {
      if (op->get_expected_min() == 0) {
        op->add_result(item.inputs.empty() ? std::string("true") : item.inputs.front());
      } else {
        op->add_result(item.inputs);
      }
      op->run_callback();
    } catch (const CLI::Error& e) {
      throw UsageError("--config", path + ": " + item.name + ": " + e.what(),
                       "fix the value in the file");
    }
  }
}

}  // namespace vkjr2::cli
