// vkjr2: the command runner.

#include <CLI/CLI.hpp>

#include <string>
#include <string_view>

#include "commands.hpp"
#include "run.hpp"

namespace {

bool has_subcommand(const CLI::App& app, const std::string& name) {
  for (const CLI::App* sub : app.get_subcommands({})) {
    if (sub->check_name(name)) return true;
  }
  return false;
}

int run(int argc, char** argv) {
  CLI::App app{"vkjr2 — Joint Restoration-for-Recognition on Vulkan compute shaders", "vkjr2"};
  app.require_subcommand(1);
  app.set_version_flag("--version", std::string("vkjr2 ") + VKJR2_VERSION);
  // Parent options are taken after the subcommand too: vkjr2 simulate ... --log-level info.
  app.fallthrough();
  vkjr2::cli::add_logging_options(app);
  app.footer(
      "Environment: VKJR2_DEVICE (index or name substring), VKJR2_VALIDATION=1 (Khronos "
      "validation layer), VKJR2_PROFILE=1 (per-kernel GPU times), VKJR2_CACHE_DIR (face models),\n"
      "VKJR2_FACE_API_DIR (face-api's model/ folder, instead of the cache's), VKJR2_ARTIFACT_DIR "
      "(trained simulator artifacts),\nVKJR2_LOG_LEVEL (as --log-level), VKJR2_DEVICE_TRAITS "
      "(lavapipe or gpu: the tuning profile).\n"
      "Exit codes: 0 success; 1 a failure during the work (unreadable or corrupt input, device "
      "error);\n2 a usage error (bad option or value, missing input, output exists without "
      "--force); 3 no Vulkan device;\n130/143 interrupted by SIGINT/SIGTERM (temporary outputs "
      "removed). Errors are one line starting \"vkjr2: error:\".\n"
      "Images up to 4096x4096 pixels.");
  vkjr2::cli::add_dataset(app);
  vkjr2::cli::add_demo(app);
  vkjr2::cli::add_demo_turbulence(app);
  vkjr2::cli::add_devices(app);
  vkjr2::cli::add_eval(app);
  vkjr2::cli::add_restore(app);
  vkjr2::cli::add_restore_train(app);
  vkjr2::cli::add_cotrain(app);
  vkjr2::cli::add_estimate(app);
  vkjr2::cli::add_gate(app);
  vkjr2::cli::add_restore_study(app);
  vkjr2::cli::add_faces(app);
  vkjr2::cli::add_simulate(app);
  vkjr2::cli::add_sim_train(app);
  vkjr2::cli::add_wave(app);
  vkjr2::cli::add_sim_validate(app);
  vkjr2::cli::add_bench(app);
  // `vkjr2 bench NAME ...`: NAME's program parses the rest (its --help too).
  if (argc > 2 && std::string_view(argv[1]) == "bench" && vkjr2::cli::is_benchmark(argv[2])) {
    return vkjr2::cli::run_benchmark(argv[2], argc - 3, argv + 3);
  }
  if (argc > 1 && argv[1][0] != '-' && !has_subcommand(app, argv[1])) {
    vkjr2::cli::print_error("unknown command '" + std::string(argv[1]) +
                            "'. Run `vkjr2 --help` for the list");
    return 2;
  }
  return vkjr2::cli::run_program(app, argc, argv);
}

}  // namespace

int main(int argc, char** argv) { return vkjr2::cli::program_main(argc, argv, run); }
