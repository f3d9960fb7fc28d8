#include "log.hpp"

#include <vkjr2/runtime/error.hpp>

#include <atomic>
#include <cstdio>
#include <cstdlib>
#include <vector>

#include "checks.hpp"

namespace vkjr2::cli {
namespace {

constexpr const char* kNames[] = {"error", "warn", "info", "debug"};
constexpr const char* kLabels[] = {"error", "warning", "info", "debug"};
std::atomic<int> g_level{int(LogLevel::warn)};
std::atomic<bool> g_verbose{false};

}  // namespace

LogLevel parse_log_level(std::string_view name) {
  for (int i = 0; i < 4; ++i)
    if (name == kNames[i]) return LogLevel(i);
  throw InvalidArgument("--log-level", "'" + std::string(name) + "' is not a log level",
                        "use error, warn, info or debug");
}

std::vector<std::string> log_level_names() { return {kNames, kNames + 4}; }

void set_log_level(LogLevel level) { g_level = int(level); }

LogLevel log_level() { return LogLevel(g_level.load()); }

void set_verbose(bool on) {
  g_verbose = on;
  if (on && log_level() < LogLevel::info) set_log_level(LogLevel::info);
}

bool verbose() { return g_verbose.load(); }

void log(LogLevel level, const std::string& message) {
  if (int(level) > g_level.load()) return;
  std::fprintf(stderr, "vkjr2: %s: %s\n", kLabels[int(level)], message.c_str());
}

Device open_device(const std::string& selector) {
  DeviceOptions options;
  options.selector = selector;
  const char* env = std::getenv("VKJR2_DEVICE");
  const std::string wanted = !selector.empty() ? selector : env != nullptr ? env : "";
  if (!wanted.empty()) {
    // A selector that names no device is a usage error, found before the
    // device is made.
    const std::vector<DeviceInfo> infos = list_devices();
    try {
      (void)select_device(infos, wanted);
    } catch (const NoDeviceError&) {
      throw;
    } catch (const InvalidArgument& e) {
      throw UsageError(selector.empty() ? "VKJR2_DEVICE" : "--device", e.problem(),
                       "pass one of the listed indices or a part of a name (`vkjr2 devices`)");
    }
  }
  Device device(options);
  const DeviceInfo& i = device.info();
  log_info("device " + std::to_string(i.index) + ": " + i.name + " (" + i.type_name() + ")");
  log_debug("driver " + i.driver_name + " " + i.driver_info + ", Vulkan " + i.api_version_string() +
            ", subgroup " + std::to_string(i.subgroup_size) + ", max storage range " +
            std::to_string(i.max_storage_buffer_range >> 20) + " MiB");
  return device;
}

}  // namespace vkjr2::cli
