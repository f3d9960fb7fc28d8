#include <vkjr2/runtime/device.hpp>
#include <vkjr2/runtime/device_traits.hpp>
#include <vkjr2/runtime/error.hpp>

#include <cstdlib>
#include <string>

namespace vkjr2 {

DeviceTraits lavapipe_traits() {
  DeviceTraits t;  // the defaults are lavapipe's measured values
  t.profile = "lavapipe";
  t.measured = true;
  return t;
}

DeviceTraits gpu_traits() {
  DeviceTraits t;
  t.profile = "gpu";
  t.measured = false;
  t.min_workgroups = 1;
  t.conv_max_row_tile = 16;
  t.conv_max_tile_accumulators = 16;
  t.depthwise_max_row_tile = 16;
  t.depthwise_max_accumulators = 16;
  t.pointwise_wide_min_pixels = 0;
  t.fft_max_log2_radix = 4;
  t.psf_fft_seconds_per_point_log = 4 * t.psf_fft_seconds_per_point_log;
  return t;
}

DeviceTraits device_traits_for(const DeviceInfo& info, std::string_view override_profile) {
  std::string name(override_profile);
  const bool from_env = name.empty();
  if (from_env) {
    if (const char* env = std::getenv("VKJR2_DEVICE_TRAITS")) name = env;
  }
  if (name == "lavapipe") return lavapipe_traits();
  if (name == "gpu") return gpu_traits();
  if (!name.empty()) {
    throw InvalidArgument(from_env ? "VKJR2_DEVICE_TRAITS" : "device traits",
                          "unknown device-traits profile '" + name + "'",
                          "use 'lavapipe' or 'gpu', or leave it unset to choose by device");
  }
  const bool llvmpipe =
      info.driver_id == VK_DRIVER_ID_MESA_LLVMPIPE ||
      (info.type == VK_PHYSICAL_DEVICE_TYPE_CPU && info.name.find("llvmpipe") != std::string::npos);
  return llvmpipe ? lavapipe_traits() : gpu_traits();
}

}  // namespace vkjr2
