#include <vkjr2/sim/blur_model.hpp>

#include <cmath>

namespace vkjr2::sim {
namespace {

// The relative sampling mismatch the blur model tolerates.
constexpr double kNyquistTolerance = 0.02;

}  // namespace

std::shared_ptr<const BlurModel> blur_model_for(
    const std::vector<std::shared_ptr<const BlurModel>>& models, double nyquist) {
  for (const auto& m : models) {
    if (m && std::fabs(nyquist / m->nyquist() - 1) <= kNyquistTolerance) return m;
  }
  return nullptr;
}

}  // namespace vkjr2::sim
