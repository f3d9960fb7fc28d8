#include <vkjr2/kernels/check.hpp>

#include <algorithm>
#include <string>

namespace vkjr2::kernels {

std::uint32_t require_f32(const Tensor& t, const char* op, const char* name) {
  if (!t.defined()) throw InvalidArgument(op, std::string(name) + " is undefined");
  if (t.dtype() != DType::f32) {
    throw InvalidArgument(op,
                          std::string(name) + " is " + dtype_name(t.dtype()) + ", expected f32");
  }
  if (t.numel() == 0) {
    throw InvalidArgument(op, std::string(name) + " " + t.shape().str() + " is empty",
                          "skip the op for empty inputs");
  }
  if (t.numel() > std::int64_t(UINT32_MAX)) {
    throw InvalidArgument(op, std::string(name) + " has more than 2^32 elements",
                          "split it into chunks");
  }
  return static_cast<std::uint32_t>(t.numel());
}

std::uint32_t require_f32_rank(const Tensor& t, int rank, const char* op, const char* name) {
  const std::uint32_t n = require_f32(t, op, name);
  if (t.shape().rank() != rank) {
    throw InvalidArgument(op, std::string(name) + " " + t.shape().str() + " has rank " +
                                  std::to_string(t.shape().rank()) + ", expected " +
                                  std::to_string(rank));
  }
  return n;
}

void require_same_shape(const Tensor& a, const Tensor& b, const char* op, const char* a_name,
                        const char* b_name) {
  if (!(a.shape() == b.shape())) {
    throw InvalidArgument(op, std::string("shapes differ: ") + a_name + " " + a.shape().str() +
                                  " vs " + b_name + " " + b.shape().str());
  }
}

void require_same_numel(const Tensor& a, const Tensor& b, const char* op, const char* a_name,
                        const char* b_name) {
  if (a.numel() != b.numel()) {
    throw InvalidArgument(op, std::string("element counts differ: ") + a_name + " " +
                                  a.shape().str() + " vs " + b_name + " " + b.shape().str());
  }
}

void require_shape(const Tensor& t, const Shape& expected, const char* op, const char* name) {
  if (!(t.shape() == expected)) {
    throw InvalidArgument(
        op, std::string(name) + " has shape " + t.shape().str() + ", expected " + expected.str());
  }
}

void require_subgroup_arithmetic(const Stream& stream, const char* op) {
  const DeviceInfo& info = stream.device().info();
  if (!info.subgroup_arithmetic || info.subgroup_size == 0) {
    throw Error(op, "device '" + info.name + "' lacks subgroup arithmetic",
                "pick another device with VKJR2_DEVICE");
  }
}

Groups subgroup_row_groups(const Stream& stream, std::uint32_t rows, const char* op) {
  require_subgroup_arithmetic(stream, op);
  const DeviceInfo& info = stream.device().info();
  return groups_1d(div_up(rows, std::max(1u, 256u / info.subgroup_size)), info);
}

}  // namespace vkjr2::kernels
