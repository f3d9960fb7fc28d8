// The command runner's messages on stderr, filtered by `--log-level`
// (or VKJR2_LOG_LEVEL): error < warn (the default) < info < debug.
// Errors are always printed (by main, with the exit code); warnings say
// what a result may lack; info says what a command picked and wrote;
// debug adds the device's details and derived parameters.
#pragma once

#include <vkjr2/runtime/device.hpp>

#include <string>
#include <string_view>
#include <vector>

namespace vkjr2::cli {

enum class LogLevel { error = 0, warn = 1, info = 2, debug = 3 };

// "error" | "warn" | "info" | "debug" (throws InvalidArgument otherwise).
LogLevel parse_log_level(std::string_view name);
std::vector<std::string> log_level_names();
void set_log_level(LogLevel level);
LogLevel log_level();

// --verbose: info messages, and the decoders' own (libpng, libjpeg, FFmpeg,
// OpenCV's log) on stderr; without it they are kept off the terminal.
void set_verbose(bool on);
bool verbose();

// One line "vkjr2: <level>: message" on stderr when level ≤ log_level().
void log(LogLevel level, const std::string& message);
inline void log_warn(const std::string& m) { log(LogLevel::warn, m); }
inline void log_info(const std::string& m) { log(LogLevel::info, m); }
inline void log_debug(const std::string& m) { log(LogLevel::debug, m); }

// The device a command runs on: DeviceOptions::selector = selector (empty:
// VKJR2_DEVICE, else the best), logged at info (name, type) and debug
// (driver, API version).
Device open_device(const std::string& selector);

}  // namespace vkjr2::cli
