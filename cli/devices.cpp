// `vkjr2 devices`: what Vulkan devices there are and what vkjr2 sees of them.
#include <vkjr2/runtime/device.hpp>

#include <nlohmann/json.hpp>

#include <cstdio>
#include <iostream>
#include <memory>
#include <string>

#include "commands.hpp"
#include "log.hpp"

namespace vkjr2::cli {
namespace {

struct DevicesArgs {
  bool json = false;
};

nlohmann::json to_json(const DeviceInfo& d, bool selected) {
  nlohmann::json heaps = nlohmann::json::array();
  for (const auto& h : d.heaps)
    heaps.push_back({{"bytes", h.size_bytes}, {"device_local", h.device_local}});
  return {{"index", d.index},
          {"name", d.name},
          {"type", d.type_name()},
          {"selected", selected},
          {"driver", d.driver_name},
          {"driver_info", d.driver_info},
          {"vulkan", d.api_version_string()},
          {"subgroup_size", d.subgroup_size},
          {"tuning", device_traits_for(d).profile},
          {"shared_memory_bytes", d.max_shared_memory_bytes},
          {"max_storage_buffer_bytes", d.max_storage_buffer_range},
          {"max_workgroup_invocations", d.max_workgroup_invocations},
          {"max_push_constant_bytes", d.max_push_constant_bytes},
          {"unified_memory", d.unified_memory},
          {"timestamps", d.timestamps},
          {"memory_heaps", heaps}};
}

void run_devices(const DevicesArgs& args) {
  const auto devices = list_devices();
  std::string selector;
  if (const char* env = std::getenv("VKJR2_DEVICE")) selector = env;
  std::uint32_t selected = UINT32_MAX;
  try {
    selected = select_device(devices, selector);
  } catch (const InvalidArgument& e) {
    log_warn(e.what());
  }
  if (args.json) {
    nlohmann::json out = nlohmann::json::array();
    for (const auto& d : devices) out.push_back(to_json(d, d.index == selected));
    std::cout << out.dump(2) << "\n";
    return;
  }
  for (const auto& d : devices) {
    std::printf("%s[%u] %s\n", d.index == selected ? "* " : "  ", d.index, d.name.c_str());
    std::printf("      type            %s\n", d.type_name().c_str());
    std::printf("      driver          %s (%s), Vulkan %s\n", d.driver_name.c_str(),
                d.driver_info.c_str(), d.api_version_string().c_str());
    std::printf("      subgroup size   %u\n", d.subgroup_size);
    const DeviceTraits traits = device_traits_for(d);
    std::printf("      tuning          %s (%s)\n", traits.profile.c_str(),
                traits.measured ? "measured on this driver" : "GPU default, not measured");
    std::printf("      shared memory   %s\n", format_bytes(d.max_shared_memory_bytes).c_str());
    std::printf("      storage buffer  %s max per binding\n",
                format_bytes(d.max_storage_buffer_range).c_str());
    std::printf("      memory          %s\n", d.unified_memory ? "unified (host-mapped tensors)"
                                                               : "device-local (staged copies)");
    for (std::size_t h = 0; h < d.heaps.size(); ++h) {
      std::printf("      heap %zu          %s%s\n", h, format_bytes(d.heaps[h].size_bytes).c_str(),
                  d.heaps[h].device_local ? " device-local" : "");
    }
  }
  std::printf("(* = the device vkjr2 uses; choose with VKJR2_DEVICE=index|name)\n");
}

}  // namespace

void add_devices(CLI::App& app) {
  auto args = std::make_shared<DevicesArgs>();
  CLI::App* cmd = app.add_subcommand("devices", "List the Vulkan devices and their properties");
  cmd->add_flag("--json", args->json, "Print a JSON array instead of text");
  cmd->footer("Examples:\n  vkjr2 devices\n  VKJR2_DEVICE=llvmpipe vkjr2 devices --json");
  cmd->callback([args] { run_devices(*args); });
}

}  // namespace vkjr2::cli
