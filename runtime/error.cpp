#include <vkjr2/runtime/error.hpp>

#include <cstdio>

namespace vkjr2 {
namespace {

std::string compose(const std::string& op, const std::string& problem, const std::string& fix,
                    VkResult result) {
  std::string msg = op + ": " + problem;
  if (result != VK_SUCCESS) {
    msg += " [";
    msg += vk_result_name(result);
    msg += "]";
  }
  if (!fix.empty()) msg += ". Fix: " + fix;
  return msg;
}

std::string_view fix_for(VkResult result) {
  switch (result) {
    case VK_ERROR_OUT_OF_HOST_MEMORY:
      return "free host memory or process smaller inputs";
    case VK_ERROR_OUT_OF_DEVICE_MEMORY:
      return "process smaller inputs (fewer frames per batch, smaller images) or pick a device "
             "with more memory via VKJR2_DEVICE";
    case VK_ERROR_DEVICE_LOST:
      return "the GPU driver reset the device (a hang or a crash in a kernel); re-run with "
             "VKJR2_VALIDATION=1 to find the faulty dispatch";
    case VK_ERROR_INITIALIZATION_FAILED:
    case VK_ERROR_INCOMPATIBLE_DRIVER:
      return "install a Vulkan driver: `apt-get install mesa-vulkan-drivers` (CPU, lavapipe) or "
             "your GPU vendor's driver, then check `vulkaninfo --summary`";
    case VK_ERROR_LAYER_NOT_PRESENT:
      return "install the validation layers (`apt-get install vulkan-validationlayers`) or unset "
             "VKJR2_VALIDATION";
    case VK_ERROR_EXTENSION_NOT_PRESENT:
    case VK_ERROR_FEATURE_NOT_PRESENT:
      return "this device lacks a required Vulkan feature; pick another with VKJR2_DEVICE";
    default:
      return "this is likely a driver problem; re-run with VKJR2_VALIDATION=1 and report it";
  }
}

}  // namespace

Error::Error(std::string op, std::string problem, std::string fix, VkResult result)
    : std::runtime_error(compose(op, problem, fix, result)),
      op_(std::move(op)),
      problem_(std::move(problem)),
      fix_(std::move(fix)),
      result_(result) {}

OutOfMemoryError::OutOfMemoryError(std::string op, std::uint64_t requested_bytes,
                                   std::uint64_t free_bytes, std::string problem, std::string fix,
                                   VkResult result)
    : Error(std::move(op), std::move(problem), std::move(fix), result),
      requested_(requested_bytes),
      free_(free_bytes) {}

InvalidArgument::InvalidArgument(std::string op, std::string problem, std::string fix)
    : Error(std::move(op), std::move(problem), std::move(fix), VK_SUCCESS) {}

std::string_view vk_result_name(VkResult result) noexcept {
  switch (result) {
#define VKJR2_CASE(x) \
  case x:             \
    return #x;
    VKJR2_CASE(VK_SUCCESS)
    VKJR2_CASE(VK_NOT_READY)
    VKJR2_CASE(VK_TIMEOUT)
    VKJR2_CASE(VK_EVENT_SET)
    VKJR2_CASE(VK_EVENT_RESET)
    VKJR2_CASE(VK_INCOMPLETE)
    VKJR2_CASE(VK_ERROR_OUT_OF_HOST_MEMORY)
    VKJR2_CASE(VK_ERROR_OUT_OF_DEVICE_MEMORY)
    VKJR2_CASE(VK_ERROR_INITIALIZATION_FAILED)
    VKJR2_CASE(VK_ERROR_DEVICE_LOST)
    VKJR2_CASE(VK_ERROR_MEMORY_MAP_FAILED)
    VKJR2_CASE(VK_ERROR_LAYER_NOT_PRESENT)
    VKJR2_CASE(VK_ERROR_EXTENSION_NOT_PRESENT)
    VKJR2_CASE(VK_ERROR_FEATURE_NOT_PRESENT)
    VKJR2_CASE(VK_ERROR_INCOMPATIBLE_DRIVER)
    VKJR2_CASE(VK_ERROR_TOO_MANY_OBJECTS)
    VKJR2_CASE(VK_ERROR_FORMAT_NOT_SUPPORTED)
    VKJR2_CASE(VK_ERROR_FRAGMENTED_POOL)
    VKJR2_CASE(VK_ERROR_UNKNOWN)
    VKJR2_CASE(VK_ERROR_OUT_OF_POOL_MEMORY)
    VKJR2_CASE(VK_ERROR_INVALID_EXTERNAL_HANDLE)
    VKJR2_CASE(VK_ERROR_FRAGMENTATION)
    VKJR2_CASE(VK_ERROR_INVALID_OPAQUE_CAPTURE_ADDRESS)
    VKJR2_CASE(VK_PIPELINE_COMPILE_REQUIRED)
    VKJR2_CASE(VK_ERROR_VALIDATION_FAILED_EXT)
#undef VKJR2_CASE
    default:
      return "VK_RESULT_UNKNOWN";
  }
}

void check(VkResult result, std::string_view op) {
  if (result == VK_SUCCESS) return;
  std::string problem = "Vulkan call failed";
  if (result == VK_ERROR_OUT_OF_DEVICE_MEMORY || result == VK_ERROR_OUT_OF_HOST_MEMORY) {
    throw OutOfMemoryError(std::string(op), 0, 0, "the device ran out of memory",
                           std::string(fix_for(result)), result);
  }
  if (result == VK_ERROR_INCOMPATIBLE_DRIVER || result == VK_ERROR_INITIALIZATION_FAILED) {
    throw NoDeviceError(std::string(op), "no usable Vulkan driver", std::string(fix_for(result)),
                        result);
  }
  throw Error(std::string(op), problem, std::string(fix_for(result)), result);
}

std::string format_bytes(std::uint64_t bytes) {
  char buf[64];
  const double b = static_cast<double>(bytes);
  if (bytes >= (1ull << 30)) {
    std::snprintf(buf, sizeof buf, "%.2f GiB", b / double(1ull << 30));
  } else if (bytes >= (1ull << 20)) {
    std::snprintf(buf, sizeof buf, "%.1f MiB", b / double(1ull << 20));
  } else if (bytes >= (1ull << 10)) {
    std::snprintf(buf, sizeof buf, "%.1f KiB", b / 1024.0);
  } else {
    std::snprintf(buf, sizeof buf, "%llu B", static_cast<unsigned long long>(bytes));
  }
  return buf;
}

}  // namespace vkjr2
