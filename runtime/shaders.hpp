// Registry of the SPIR-V compiled at build time from shaders/*.comp and
// embedded in the library (cmake/vkjr2Shaders.cmake generates the definitions).
#pragma once

#include <cstdint>
#include <span>
#include <string_view>
#include <vector>

namespace vkjr2::shaders {

// SPIR-V words of shaders/NAME.comp; empty when no such shader was built.
std::span<const std::uint32_t> find(std::string_view name) noexcept;

// Names of all embedded shaders.
std::vector<std::string_view> names();

}  // namespace vkjr2::shaders
