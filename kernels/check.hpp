// Argument checks shared by the typed ops in kernels/: each throws
// InvalidArgument naming the op, the argument and what was expected.
#pragma once

#include <vkjr2/runtime/stream.hpp>

#include <cstdint>

namespace vkjr2::kernels {

// t is defined, f32, non-empty and addressable with 32-bit indices; returns numel.
std::uint32_t require_f32(const Tensor& t, const char* op, const char* name);
// Same as require_f32, and t has exactly `rank` dimensions.
std::uint32_t require_f32_rank(const Tensor& t, int rank, const char* op, const char* name);
// a and b have the same shape.
void require_same_shape(const Tensor& a, const Tensor& b, const char* op, const char* a_name,
                        const char* b_name);
// a and b have the same number of elements.
void require_same_numel(const Tensor& a, const Tensor& b, const char* op, const char* a_name,
                        const char* b_name);
// t has shape `expected`.
void require_shape(const Tensor& t, const Shape& expected, const char* op, const char* name);

// The stream's device has subgroup arithmetic (subgroupAdd & co.) in compute
// shaders, which the reduction kernels need.
void require_subgroup_arithmetic(const Stream& stream, const char* op);
// Workgroups of 256 invocations for kernels that give each of `rows` rows one
// subgroup; checks require_subgroup_arithmetic first.
Groups subgroup_row_groups(const Stream& stream, std::uint32_t rows, const char* op);

}  // namespace vkjr2::kernels
