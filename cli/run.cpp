#include "run.hpp"

#include <vkjr2/runtime/device.hpp>

#include <opencv2/core/utils/logger.hpp>

#include <algorithm>
#include <cstdio>
#include <iostream>
#include <new>
#include <string>

#include "checks.hpp"
#include "cleanup.hpp"
#include "log.hpp"

namespace vkjr2::cli {
namespace {

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

int parse_and_run(CLI::App& app, int argc, char** argv) {
  try {
    app.parse(argc, argv);
  } catch (const CLI::CallForHelp& e) {
    return app.exit(e);
  } catch (const CLI::CallForAllHelp& e) {
    return app.exit(e);
  } catch (const CLI::CallForVersion& e) {
    return app.exit(e);
  } catch (const CLI::ParseError& e) {
    print_error(std::string(e.what()) + " (see `" + app.get_name() + command_path(app) +
                " --help`)");
    return 2;
  } catch (const UsageError& e) {
    print_error(describe_error(e));
    return 2;
  } catch (const NoDeviceError& e) {
    print_error(describe_error(e));
    return 3;
  } catch (const Error& e) {
    print_error(describe_error(e));
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

// The signal clean-up, and OpenCV's own log silenced: first thing in main.
void start_program() {
  install_signal_cleanup();
  // OpenCV's own log lines ("[ WARN:0@...]") only with --verbose.
  cv::utils::logging::setLogLevel(cv::utils::logging::LOG_LEVEL_SILENT);
}

}  // namespace

void print_error(std::string text) {
  std::replace(text.begin(), text.end(), '\n', ' ');
  while (!text.empty() && (text.back() == ' ' || text.back() == '.')) text.pop_back();
  // What the command printed comes first, whole.
  std::cout.flush();
  std::fflush(stdout);
  std::fprintf(stderr, "vkjr2: error: %s\n", text.c_str());
}

void add_logging_options(CLI::App& app) {
  app.add_flag_function(
      "--verbose",
      [](std::int64_t) {
        set_verbose(true);
        cv::utils::logging::setLogLevel(cv::utils::logging::LOG_LEVEL_WARNING);
      },
      "Info messages, and the image and video decoders' own messages (libpng, libjpeg, FFmpeg, "
      "OpenCV), which are hidden otherwise");
  app.add_option_function<std::string>(
         "--log-level", [](const std::string& v) { set_log_level(parse_log_level(v)); },
         "Messages on stderr: error, warn (default), info (device, files written), debug")
      ->envname("VKJR2_LOG_LEVEL")
      ->check(CLI::IsMember(log_level_names()));
}

int program_main(int argc, char** argv, int (*run)(int, char**)) noexcept {
  start_program();
  try {
    return run(argc, argv);
  } catch (...) {  // building the parser itself failed (out of memory)
    print_error("unexpected failure while starting");
    return 1;
  }
}

int run_program(CLI::App& app, int argc, char** argv) {
  int code = 1;
  try {
    code = parse_and_run(app, argc, argv);
  } catch (...) {  // printing an error itself failed (out of memory)
    code = 1;
  }
  if (code != 0) cleanup_after_failure();
  return code;
}

}  // namespace vkjr2::cli
