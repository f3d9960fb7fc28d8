// What jr2/'s trainers share (internal): seeds from two numbers, wall time,
// and the global gradient norm with clipping.
#pragma once

#include <vkjr2/kernels/basic.hpp>
#include <vkjr2/kernels/elementwise.hpp>
#include <vkjr2/kernels/reduce.hpp>
#include <vkjr2/nets/autograd.hpp>
#include <vkjr2/runtime/error.hpp>

#include <chrono>
#include <cmath>
#include <cstdint>
#include <filesystem>
#include <map>
#include <string>
#include <utility>
#include <vector>

#include "text_and_draws.hpp"

namespace vkjr2::jr2::detail {

// A seed from two numbers.
inline std::uint64_t mix(std::uint64_t a, std::uint64_t b) {
  return splitmix_finalize(a * kGoldenGamma + b + 0x632be59bd9b4e019ULL);
}

using Clock = std::chrono::steady_clock;
inline double seconds_since(Clock::time_point t0) {
  return std::chrono::duration<double>(Clock::now() - t0).count();
}

// A resume needs the checkpoint's settings: throws InvalidArgument (op)
// naming every key of `now` whose value the checkpoint's metadata lacks or
// holds otherwise.
inline void require_same_settings(const char* op, const std::filesystem::path& path,
                                  const std::map<std::string, std::string>& saved,
                                  const std::map<std::string, std::string>& now) {
  std::string differ;
  for (const auto& [key, value] : now) {
    const auto it = saved.find(key);
    if (it == saved.end() || it->second != value) {
      differ += differ.empty() ? "" : ", ";
      differ += key + " (checkpoint ";
      differ += it == saved.end() ? std::string("none") : it->second;
      differ += ", now " + value + ")";
    }
  }
  if (!differ.empty()) {
    throw InvalidArgument(op, path.string() + " was made with other settings: " + differ,
                          "resume with the checkpoint's settings, or start a new run");
  }
}

// The global L2 norm of the parameters' gradients, and clipping to a norm.
class GradientNorm {
 public:
  GradientNorm(const Device& device, std::vector<std::pair<std::string, nets::Var>> params)
      : params_(std::move(params)) {
    for (const auto& [name, v] : params_) squares_.push_back(Tensor::empty(device, v.shape()));
    // One value per parameter, 16 bytes apart (aligned views).
    sums_ =
        Tensor::empty(device, Shape{std::int64_t(4 * std::max<std::size_t>(1, params_.size()))});
  }

  // Records Σ g² per parameter on `stream` (run the stream, then call norm()).
  void record(Stream& stream) const {
    for (std::size_t i = 0; i < params_.size(); ++i) {
      const nets::Var& v = params_[i].second;
      if (!v.has_grad()) continue;
      const Tensor& sq = squares_[i];
      kernels::mul(stream, v.grad(), v.grad(), sq);
      kernels::sum_all(stream, sq.reshape(Shape{sq.numel()}),
                       sums_.view(Shape{1}, 4 * std::int64_t(i)));
    }
  }
  // After the stream ran: the norm (in parameter order, so deterministic).
  double norm() const {
    const std::vector<float> s = sums_.download();
    double sum = 0;
    for (std::size_t i = 0; i < params_.size(); ++i) {
      if (params_[i].second.has_grad()) sum += double(s[4 * i]);
    }
    return std::sqrt(sum);
  }
  // Scales every gradient by max_norm / norm when norm > max_norm > 0.
  void clip(Stream& stream, double norm, double max_norm) const {
    if (max_norm <= 0 || norm <= max_norm) return;
    const float f = float(max_norm / norm);
    for (std::size_t i = 0; i < params_.size(); ++i) {
      const nets::Var& v = params_[i].second;
      if (!v.has_grad()) continue;
      kernels::scale_shift(stream, v.grad(), f, 0.f, squares_[i]);
      kernels::copy(stream, squares_[i], v.grad());
    }
  }

 private:
  std::vector<std::pair<std::string, nets::Var>> params_;
  std::vector<Tensor> squares_;
  Tensor sums_;
};

}  // namespace vkjr2::jr2::detail
