#include <vkjr2/kernels/check.hpp>
#include <vkjr2/kernels/random.hpp>

#include <cmath>
#include <string>

namespace vkjr2::kernels {
namespace {

constexpr std::uint32_t kPerGroup = 1024;  // 256 invocations × 4 values

struct RandnPush {
  std::uint32_t n;
  std::uint32_t stream_id;
  std::uint32_t seed_lo, seed_hi;
  std::uint32_t mode;
  float a, b;
};
static_assert(sizeof(RandnPush) <= 128);

enum Mode : std::uint32_t { kFill = 0, kAr1 = 1, kSensor = 2 };

void dispatch(Stream& stream, const Tensor& x, const Tensor& y, std::uint32_t n, Mode mode, float a,
              float b, std::uint64_t seed, std::uint32_t stream_id) {
  static const KernelDef kRandn{
      "randn", {BindingKind::storage, BindingKind::storage}, sizeof(RandnPush)};
  const RandnPush push{n,
                       stream_id,
                       static_cast<std::uint32_t>(seed & 0xffffffffu),
                       static_cast<std::uint32_t>(seed >> 32),
                       mode,
                       a,
                       b};
  // mode 1 reads y (the AR(1) state); modes 0 and 2 only write it.
  const Arg out_arg = mode == kAr1 ? inout(y) : out(y);
  stream.dispatch(kRandn, {in(x), out_arg}, push,
                  groups_1d(div_up(n, kPerGroup), stream.device().info()));
}

void require_finite(float v, const char* op, const char* name) {
  if (!std::isfinite(v)) {
    throw InvalidArgument(op, std::string(name) + " must be finite, got " + std::to_string(v));
  }
}

}  // namespace

void randn(Stream& stream, const Tensor& out, std::uint64_t seed, std::uint32_t stream_id,
           float mean, float stddev) {
  const std::uint32_t n = require_f32(out, "randn", "out");
  require_finite(mean, "randn", "mean");
  require_finite(stddev, "randn", "stddev");
  dispatch(stream, out, out, n, kFill, mean, stddev, seed, stream_id);
}

void randn_ar1(Stream& stream, const Tensor& x, float rho, std::uint64_t seed,
               std::uint32_t stream_id) {
  const std::uint32_t n = require_f32(x, "randn_ar1", "x");
  if (!(rho >= 0.f && rho <= 1.f)) {
    throw InvalidArgument(
        "randn_ar1", "rho must be in [0, 1] (a lag-1 correlation), got " + std::to_string(rho));
  }
  const float innovation = std::sqrt(std::max(0.f, 1.f - rho * rho));
  dispatch(stream, x, x, n, kAr1, rho, innovation, seed, stream_id);
}

void sensor_noise(Stream& stream, const Tensor& x, const Tensor& y, float shot, float read_std,
                  std::uint64_t seed, std::uint32_t stream_id) {
  const std::uint32_t n = require_f32(x, "sensor_noise", "x");
  require_f32(y, "sensor_noise", "y");
  require_same_numel(x, y, "sensor_noise", "x", "y");
  if (!(shot >= 0.f) || !std::isfinite(shot)) {
    throw InvalidArgument(
        "sensor_noise",
        "shot (variance per unit of signal) must be finite and >= 0, got " + std::to_string(shot));
  }
  if (!(read_std >= 0.f) || !std::isfinite(read_std)) {
    throw InvalidArgument("sensor_noise",
                          "read_std must be finite and >= 0, got " + std::to_string(read_std));
  }
  dispatch(stream, x, y, n, kSensor, shot, read_std * read_std, seed, stream_id);
}

}  // namespace vkjr2::kernels
