// vkjr2: the command runner.
#include <vkjr2/runtime/device.hpp>

#include <CLI/CLI.hpp>
#include <nlohmann/json.hpp>

#include <cstdio>
#include <iostream>
#include <string>

#include "commands.hpp"
#include "log.hpp"

namespace {

bool has_subcommand(const CLI::App& app, const std::string& name) {
  for (const CLI::App* sub : app.get_subcommands({})) {
    if (sub->check_name(name)) return true;
  }
  return false;
}

}  // namespace

int run(int argc, char** argv) {
  CLI::App app{"vkjr2 — Joint Restoration-for-Recognition on Vulkan compute shaders"};
  app.require_subcommand(1);
  app.set_version_flag("--version", std::string("vkjr2 ") + VKJR2_VERSION);
  // Parent options are taken after the subcommand too: vkjr2 simulate ... --log-level info.
  app.fallthrough();
  app.add_option_function<std::string>(
         "--log-level",
         [](const std::string& v) { vkjr2::cli::set_log_level(vkjr2::cli::parse_log_level(v)); },
         "Messages on stderr: error, warn (default), info (device, files written), debug")
      ->envname("VKJR2_LOG_LEVEL")
      ->check(CLI::IsMember(vkjr2::cli::log_level_names()));
  app.footer(
      "Environment: VKJR2_DEVICE (index or name substring), VKJR2_VALIDATION=1 (Khronos "
      "validation layer), VKJR2_PROFILE=1 (per-kernel GPU times), VKJR2_CACHE_DIR (face models),\n"
      "VKJR2_ARTIFACT_DIR (trained simulator artifacts), VKJR2_LOG_LEVEL (as --log-level).\n"
      "Exit codes: 0 success, 1 runtime error (message on stderr), 2 bad command line, "
      "3 no Vulkan device.");
  vkjr2::cli::add_demo(app);
  vkjr2::cli::add_devices(app);
  vkjr2::cli::add_faces(app);
  vkjr2::cli::add_simulate(app);
  vkjr2::cli::add_sim_train(app);
  vkjr2::cli::add_wave(app);
  vkjr2::cli::add_sim_validate(app);
  vkjr2::cli::add_bench(app);
  if (argc > 1 && argv[1][0] != '-' && !has_subcommand(app, argv[1])) {
    std::fprintf(stderr, "vkjr2: error: unknown command '%s'. Run `vkjr2 --help` for the list.\n",
                 argv[1]);
    return 2;
  }
  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    const int code = app.exit(e);  // prints help, version or the usage error
    return code == 0 ? 0 : 2;
  } catch (const vkjr2::NoDeviceError& e) {
    std::fprintf(stderr, "vkjr2: error: %s\n", e.what());
    return 3;
  } catch (const vkjr2::Error& e) {
    std::fprintf(stderr, "vkjr2: error: %s\n", e.what());
    return 1;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "vkjr2: error: %s\n", e.what());
    return 1;
  }
  return 0;
}

int main(int argc, char** argv) {
  try {
    return run(argc, argv);
  } catch (...) {  // building the parser itself failed (out of memory)
    std::fprintf(stderr, "vkjr2: error: unexpected failure while starting\n");
    return 1;
  }
}
