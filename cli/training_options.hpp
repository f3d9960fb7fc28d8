// What the training commands (restore-train, cotrain) share: --config FILE
// (a JSON or YAML map of a command's long option names, without the
// dashes, to values; lists for multi-value options; the command line wins),
// the optimizer schedule's options, and the run's files and flags.
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

// --steps, --lr, --min-lr, --weight-decay, --warmup, --clip-grad into the
// fields of that name of a training options struct (AdamW, linear warm-up,
// cosine decay, gradient-norm clipping).
template <class Options>
void add_schedule_options(CLI::App* cmd, Options& o) {
  cmd->add_option("--steps", o.steps, "Training steps")
      ->default_val(o.steps)
      ->check(integer_range(1, 10000000));
  cmd->add_option("--lr", o.lr, "Peak learning rate")
      ->default_val(o.lr)
      ->check(finite_range(1e-8, 1));
  cmd->add_option("--min-lr", o.min_lr, "Learning rate at the end of the cosine")
      ->default_val(o.min_lr)
      ->check(finite_range(0, 1));
  cmd->add_option("--weight-decay", o.weight_decay, "AdamW decoupled weight decay")
      ->default_val(o.weight_decay)
      ->check(finite_range(0, 0.999));
  cmd->add_option("--warmup", o.warmup_steps, "Linear warm-up steps")
      ->default_val(o.warmup_steps)
      ->check(integer_range(0, 10000000));
  cmd->add_option("--clip-grad", o.clip_grad_norm, "Clip the global gradient norm (0: off)")
      ->default_val(o.clip_grad_norm)
      ->check(finite_range(0, 1e6));
}

// A training run's files and flags.
struct TrainRun {
  std::string output, checkpoint, log_path, device, config;
  int checkpoint_every = 100, eval_every = 250;
  bool resume = false, json_out = false, quiet = false, force = false;
};

// --checkpoint, --checkpoint-every, --eval-every, --log, --resume, --device,
// --json, --quiet, --force and --config (applied by apply_config_file).
inline void add_run_options(CLI::App* cmd, TrainRun& r, const std::string& log_help) {
  cmd->add_option("--config", r.config,
                  "JSON or YAML map of these options (long names, no dashes; the command line "
                  "wins)");
  cmd->add_option("--checkpoint", r.checkpoint, "Checkpoint file (default: OUT.ckpt)");
  cmd->add_option("--checkpoint-every", r.checkpoint_every, "Steps between checkpoints")
      ->default_val(r.checkpoint_every)
      ->check(integer_range(1, 10000000));
  cmd->add_option("--eval-every", r.eval_every, "Steps between held-out scores")
      ->default_val(r.eval_every)
      ->check(integer_range(1, 10000000));
  cmd->add_option("--log", r.log_path, log_help);
  cmd->add_flag("--resume", r.resume, "Go on from --checkpoint (same settings)");
  cmd->add_option("--device", r.device,
                  "Vulkan device index or name substring (else VKJR2_DEVICE)");
  cmd->add_flag("--json", r.json_out, "Print JSON instead of text");
  cmd->add_flag("--quiet", r.quiet, "No progress bar");
  cmd->add_flag("--force", r.force, "Replace existing output and checkpoint files");
}

// OUT must be a new .safetensors (or --force); the checkpoint (default
// OUT.ckpt) must exist with --resume, else be new (or --force).
inline void check_run_files(TrainRun& r) {
  check_extension(r.output, {".safetensors"}, "OUT");
  check_output_file(r.output, r.force, "OUT");
  if (r.checkpoint.empty()) r.checkpoint = r.output + ".ckpt";
  if (r.resume) {
    check_input_file(r.checkpoint, "--checkpoint");
  } else {
    check_output_file(r.checkpoint, r.force, "--checkpoint");
  }
}

}  // namespace vkjr2::cli
