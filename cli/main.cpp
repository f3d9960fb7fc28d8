// vkjr2: the command runner.
#include <vkjr2/runtime/device.hpp>

#include <CLI/CLI.hpp>
#include <opencv2/core/utils/logger.hpp>

#include <algorithm>
#include <cctype>
#include <cstdio>
#include <iostream>
#include <new>
#include <string>

#include "checks.hpp"
#include "cleanup.hpp"
#include "commands.hpp"
#include "log.hpp"

namespace {

// One line on stderr: "vkjr2: error: <what>".
void print_error(std::string text) {
  std::replace(text.begin(), text.end(), '\n', ' ');
  while (!text.empty() && (text.back() == ' ' || text.back() == '.')) text.pop_back();
  // What the command printed comes first, whole.
  std::cout.flush();
  std::fflush(stdout);
  std::fprintf(stderr, "vkjr2: error: %s\n", text.c_str());
}

// The deepest subcommand the parse reached ("simulate", "bench sim").
std::string command_path(const CLI::App& app) {
  std::string path;
  const CLI::App* at = &app;
  for (;;) {
    const auto subs = at->get_subcommands();
    if (subs.empty()) break;
    at = subs.front();
    path += " " + at->get_name();
  }
  return path;
}

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
  app.add_flag_function(
      "--verbose",
      [](std::int64_t) {
        vkjr2::cli::set_verbose(true);
        cv::utils::logging::setLogLevel(cv::utils::logging::LOG_LEVEL_WARNING);
      },
      "Info messages, and the image and video decoders' own messages (libpng, libjpeg, FFmpeg, "
      "OpenCV), which are hidden otherwise");
  app.add_option_function<std::string>(
         "--log-level",
         [](const std::string& v) { vkjr2::cli::set_log_level(vkjr2::cli::parse_log_level(v)); },
         "Messages on stderr: error, warn (default), info (device, files written), debug")
      ->envname("VKJR2_LOG_LEVEL")
      ->check(CLI::IsMember(vkjr2::cli::log_level_names()));
  app.footer(
      "Environment: VKJR2_DEVICE (index or name substring), VKJR2_VALIDATION=1 (Khronos "
      "validation layer), VKJR2_PROFILE=1 (per-kernel GPU times), VKJR2_CACHE_DIR (face models),\n"
      "VKJR2_FACE_API_DIR (face-api's model/ folder, instead of the cache's), VKJR2_ARTIFACT_DIR "
      "(trained simulator artifacts),\nVKJR2_LOG_LEVEL (as --log-level).\n"
      "Exit codes: 0 success; 1 a failure during the work (unreadable or corrupt input, device "
      "error);\n2 a usage error (bad option or value, missing input, output exists without "
      "--force); 3 no Vulkan device;\n130/143 interrupted by SIGINT/SIGTERM (temporary outputs "
      "removed). Errors are one line starting \"vkjr2: error:\".\n"
      "Images up to 4096x4096 pixels.");
  vkjr2::cli::add_demo(app);
  vkjr2::cli::add_devices(app);
  vkjr2::cli::add_faces(app);
  vkjr2::cli::add_simulate(app);
  vkjr2::cli::add_sim_train(app);
  vkjr2::cli::add_wave(app);
  vkjr2::cli::add_sim_validate(app);
  vkjr2::cli::add_bench(app);
  if (argc > 1 && argv[1][0] != '-' && !has_subcommand(app, argv[1])) {
    print_error("unknown command '" + std::string(argv[1]) + "'. Run `vkjr2 --help` for the list");
    return 2;
  }
  try {
    app.parse(argc, argv);
  } catch (const CLI::CallForHelp& e) {
    return app.exit(e);
  } catch (const CLI::CallForAllHelp& e) {
    return app.exit(e);
  } catch (const CLI::CallForVersion& e) {
    return app.exit(e);
  } catch (const CLI::ParseError& e) {
    print_error(std::string(e.what()) + " (see `vkjr2" + command_path(app) + " --help`)");
    return 2;
  } catch (const vkjr2::cli::UsageError& e) {
    print_error(vkjr2::cli::describe_error(e));
    return 2;
  } catch (const vkjr2::NoDeviceError& e) {
    print_error(vkjr2::cli::describe_error(e));
    return 3;
  } catch (const vkjr2::Error& e) {
    print_error(vkjr2::cli::describe_error(e));
    return 1;
  } catch (const std::bad_alloc&) {
    print_error("out of host memory. Fix: process smaller inputs or free memory");
    return 1;
  } catch (const std::exception& e) {
    print_error(e.what());
    return 1;
  }
  return 0;
}

int main(int argc, char** argv) {
  vkjr2::cli::install_signal_cleanup();
  // OpenCV's own log lines ("[ WARN:0@...]") only with --verbose.
  cv::utils::logging::setLogLevel(cv::utils::logging::LOG_LEVEL_SILENT);
  int code = 1;
  try {
    code = run(argc, argv);
  } catch (...) {  // building the parser itself failed (out of memory)
    print_error("unexpected failure while starting");
    code = 1;
  }
  if (code != 0) vkjr2::cli::cleanup_after_failure();
  return code;
}
