// The one way a vkjr2 program turns a command line into an exit code: the
// `vkjr2` command runner and the benchmark programs it runs (bench/) share it,
// so that every one prints errors, cleans up and exits alike.
//
// run_program(argc, argv, app) parses with CLI11 and runs the callbacks;
// errors become one line on stderr, "vkjr2: error: <what>. Fix: <what to do>",
// and the exit code: 0 success; 1 a failure during the work; 2 a usage error;
// 3 no Vulkan device. Signals (SIGINT, SIGTERM, SIGHUP) and failures remove
// the temporary outputs (cleanup.hpp).
#pragma once

#include <CLI/CLI.hpp>

#include <string>

namespace vkjr2::cli {

// main() of a vkjr2 program: start_program(), then run(argc, argv) (which
// builds the parser and calls run_program); a failure while building the
// parser itself is one error line and exit code 1.
int program_main(int argc, char** argv, int (*run)(int, char**)) noexcept;

// Parses and runs `app` (its subcommands' callbacks do the work) and returns
// the exit code; cleans up after a failure.
int run_program(CLI::App& app, int argc, char** argv);

// One line on stderr: "vkjr2: error: <text>" (newlines folded, stdout flushed first).
void print_error(std::string text);

// Adds --verbose and --log-level (with VKJR2_LOG_LEVEL) to `app`.
void add_logging_options(CLI::App& app);

}  // namespace vkjr2::cli
