// How a kernel (one shaders/NAME.comp) is described to the runtime, and the
// arguments a dispatch binds. Typed ops in kernels/ wrap these.
#pragma once

#include <vkjr2/runtime/tensor.hpp>

#include <cstdint>
#include <string_view>
#include <vector>

namespace vkjr2 {

// The descriptor type of one binding, in binding order (binding 0, 1, ...).
enum class BindingKind : std::uint8_t {
  storage,  // storage buffer (read and/or write)
  texel,    // uniform texel buffer (read only; vector gathers on lavapipe)
  uniform,  // uniform buffer (read only; small, e.g. weights)
};

enum class Access : std::uint8_t { read, write, read_write };

struct KernelDef {
  std::string_view shader;  // file stem in shaders/
  std::vector<BindingKind> bindings;
  std::uint32_t push_bytes = 0;  // sizeof the push-constant struct, 0 for none
};

// One bound tensor.
struct Arg {
  Tensor tensor;
  BindingKind kind = BindingKind::storage;
  Access access = Access::read;
  VkFormat format = VK_FORMAT_R32_SFLOAT;  // texel buffers only
};

inline Arg in(const Tensor& t) { return {t, BindingKind::storage, Access::read}; }
inline Arg out(const Tensor& t) { return {t, BindingKind::storage, Access::write}; }
inline Arg inout(const Tensor& t) { return {t, BindingKind::storage, Access::read_write}; }
inline Arg texel(const Tensor& t, VkFormat format = VK_FORMAT_R32_SFLOAT) {
  return {t, BindingKind::texel, Access::read, format};
}
inline Arg uniform(const Tensor& t) { return {t, BindingKind::uniform, Access::read}; }

struct Groups {
  std::uint32_t x = 1, y = 1, z = 1;
};

// Workgroups needed to cover n items, local_size items per group.
constexpr std::uint32_t div_up(std::uint64_t n, std::uint64_t local_size) {
  return static_cast<std::uint32_t>((n + local_size - 1) / local_size);
}

}  // namespace vkjr2

namespace vkjr2 {

// A 1-D grid of n_groups workgroups, folded into y when it exceeds the
// device's x limit. Shaders recover the index with linear_group() from
// shaders/common.glsl and must bounds-check.
inline Groups groups_1d(std::uint64_t n_groups, const DeviceInfo& info) {
  const std::uint64_t max_x = info.max_workgroup_count[0];
  if (n_groups <= max_x) return {static_cast<std::uint32_t>(n_groups), 1, 1};
  const std::uint64_t y = (n_groups + max_x - 1) / max_x;
  return {static_cast<std::uint32_t>((n_groups + y - 1) / y), static_cast<std::uint32_t>(y), 1};
}

// Lanes per workgroup (a shader's local_size_x_id) for `invocations`
// invocations: max_lanes, halved down to 8 while that would leave fewer
// than min_workgroups workgroups (DeviceTraits::min_workgroups: 4 on
// lavapipe, which runs a workgroup on one CPU thread, so that every thread
// gets one; 1 on a GPU).
inline std::uint32_t group_lanes(std::uint64_t invocations, std::uint32_t min_workgroups,
                                 std::uint32_t max_lanes = 64) {
  std::uint32_t lanes = max_lanes;
  while (lanes > 8 && invocations < std::uint64_t(lanes) * min_workgroups) lanes /= 2;
  return lanes;
}

}  // namespace vkjr2
