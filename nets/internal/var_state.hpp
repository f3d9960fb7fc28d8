// Internal to the nets layer (not installed): what a Var shares with its
// copies. Included as "internal/var_state.hpp" from nets/*.cpp only.
#pragma once

#include <vkjr2/kernels/planes.hpp>
#include <vkjr2/runtime/tensor.hpp>

#include <cstdint>

namespace vkjr2::nets::detail {

struct VarState {
  Tensor value;  // padded Vars: the planes' data
  // Padded Vars: the image's shape and where it lies in value (plain: none).
  Shape padded_shape;
  kernels::PlaneLayout layout;
  Tensor grad;  // undefined until a gradient reaches this Var
  bool requires_grad = false;
  std::uint64_t version = 0;  // counts writes to value (Var::mark_modified)
};

}  // namespace vkjr2::nets::detail
