#include <vkjr2/kernels/basic.hpp>
#include <vkjr2/kernels/check.hpp>
#include <vkjr2/kernels/elementwise.hpp>
#include <vkjr2/kernels/layout.hpp>
#include <vkjr2/kernels/psf_conv.hpp>
#include <vkjr2/kernels/random.hpp>
#include <vkjr2/kernels/resize.hpp>
#include <vkjr2/kernels/warp.hpp>
#include <vkjr2/runtime/error.hpp>
#include <vkjr2/sim/simulator.hpp>
#include <vkjr2/sim/tilt.hpp>

#include <algorithm>
#include <cmath>
#include <string>
#include <vector>

namespace vkjr2::sim {
namespace {

constexpr char kOp[] = "Simulator";
constexpr int kMaxPsfChannels = 4;  // psf_conv takes up to 4 channels per call: a group's limit
// Mixed into the seed for the sensor noise, so that it never repeats the
// turbulence seeds' numbers.
constexpr std::uint64_t kNoiseSalt = 0x9e3779b97f4a7c15ull;

}  // namespace

Simulator::~Simulator() = default;

Simulator::Simulator(const Device& device, const Params& params,
                     std::shared_ptr<const BlurModel> blur, const SimOptions& options)
    : Simulator(device, params,
                blur ? std::vector<std::shared_ptr<const BlurModel>>{std::move(blur)}
                     : std::vector<std::shared_ptr<const BlurModel>>{},
                options) {}

Simulator::Simulator(const Device& device, const Params& params,
                     std::vector<std::shared_ptr<const BlurModel>> blur_models,
                     const SimOptions& options)
    : device_(device), params_(params), derived_(derive(params)), options_(options) {
  if (options.blur) {
    std::erase(blur_models, nullptr);
    if (blur_models.empty()) {
      throw InvalidArgument(kOp, "blur is on but no blur model (PSF basis + P2S network) was given",
                            "load one (vkjr2 sim-train makes it) or turn blur off");
    }
    const double lambda0 = derived_.channels[0].wavelength_m;
    for (int c = 0; c < params.image.channels; ++c) {
      const ChannelDerived& cd = derived_.channels[std::size_t(c)];
      const std::shared_ptr<const BlurModel> model = blur_model_for(blur_models, cd.nyquist);
      if (!model) {
        std::string offered;
        for (const auto& m : blur_models)
          offered += (offered.empty() ? "" : ", ") + std::to_string(m->nyquist());
        throw InvalidArgument(
            kOp,
            "channel " + std::to_string(c) + " (λ = " + std::to_string(cd.wavelength_m * 1e9) +
                " nm) samples at Nyquist ratio " + std::to_string(cd.nyquist) +
                " (λ f / (2 D p)) but the PSF basis" +
                (blur_models.size() > 1 ? "es were" : " was") + " made for " + offered,
            "train a basis for these optics: vkjr2 sim-train OUT --config FILE --channel " +
                std::to_string(c) + ", and pass it with the others");
      }
      if (model->j_max() > params.zernike_modes) {
        throw InvalidArgument(kOp,
                              "the blur model takes a_4..a_" + std::to_string(model->j_max()) +
                                  " but the parameters simulate modes up to j = " +
                                  std::to_string(params.zernike_modes),
                              "set zernike_modes to at least " + std::to_string(model->j_max()));
      }
      const auto scale = static_cast<float>(lambda0 / cd.wavelength_m);
      if (!groups_.empty() && groups_.back().model == model &&
          groups_.back().coefficient_scale == scale && groups_.back().count < kMaxPsfChannels) {
        ++groups_.back().count;
      } else {
        BlurGroup g;
        g.first = c;
        g.count = 1;
        g.model = model;
        g.coefficient_scale = scale;
        groups_.push_back(std::move(g));
      }
    }
  }
  FieldOptions field_options = options.field;
  // Without blur only the tilts matter, and they allow a much coarser grid.
  if (!options.blur && field_options.j_max == 0) field_options.j_max = 3;
  field_ = std::make_unique<TurbulenceField>(device_, params_, field_options);
  const ImageShape& im = params_.image;
  const std::int64_t b = im.batch, c = im.channels, h = im.height, w = im.width;
  flow_ = Tensor::empty(device_, {b, 2, h, w});
  warped_ = Tensor::empty(device_, {b, c, h, w});
  if (!groups_.empty()) blurred_ = Tensor::empty(device_, {b, c, h, w});
  for (BlurGroup& g : groups_) {
    const Tensor& basis = g.model->basis();
    const std::int64_t k = basis.shape()[0], s = basis.shape()[1];
    // Groups of one model and scale (more than 4 channels, or channels of
    // one wavelength apart) share one β: the P2S pass runs once for them.
    const auto same = std::find_if(groups_.begin(), groups_.end(), [&](const BlurGroup& e) {
      return e.model == g.model && e.coefficient_scale == g.coefficient_scale;
    });
    if (&*same != &g) {
      g.shares_beta = true;
      g.beta_grid = same->beta_grid;
      g.beta = same->beta;
    } else {
      g.beta_grid = Tensor::empty(device_, {b, k, field_->grid_h(), field_->grid_w()});
      g.beta = Tensor::empty(device_, {b, k, h, w});
    }
    g.norm = Tensor::empty(device_, {b, 1, h, w});
    if (groups_.size() == 1) {
      g.warped = warped_;
      g.blurred = blurred_;
    } else {
      g.warped = Tensor::empty(device_, {b, g.count, h, w});
      g.blurred = Tensor::empty(device_, {b, g.count, h, w});
    }
    const DeviceTraits& traits = device_.traits();
    if (kernels::psf_conv_path(traits, b, g.count, k, s, h, w) == kernels::PsfConvPath::fft) {
      g.fft = std::make_unique<kernels::PsfConvFft>(device_, basis, b, g.count, h, w);
    }
  }
}

const Simulator::BlurGroup& Simulator::group_of(int channel) const {
  if (channel < 0 || channel >= params_.image.channels) {
    throw InvalidArgument("Simulator", "channel " + std::to_string(channel) + " is outside 0.." +
                                           std::to_string(params_.image.channels - 1));
  }
  for (const BlurGroup& g : groups_)
    if (channel < g.first + g.count) return g;
  throw InvalidArgument("Simulator", "the simulator has no blur (it was made without one)");
}

const Tensor& Simulator::beta(int channel) const {
  static const Tensor kNone;
  if (groups_.empty()) return kNone;
  return group_of(channel).beta;
}

const BlurModel* Simulator::blur_model(int channel) const {
  if (groups_.empty()) return nullptr;
  return group_of(channel).model.get();
}

void Simulator::reset(std::uint64_t seed) {
  seed_ = seed;
  frame_ = -1;
  field_->reset(seed);
}

void Simulator::frame(Stream& stream, const Tensor& x, const Tensor& y) {
  const ImageShape& im = params_.image;
  const Shape shape{im.batch, im.channels, im.height, im.width};
  kernels::require_shape(x, shape, kOp, "x");
  kernels::require_shape(y, shape, kOp, "y");
  ++frame_;
  input_ = x;
  field_->next(stream);
  mark(stream, &FrameStages::fields);
  if (options_.tilt) {
    kernels::resize(stream, field_->tilt_px(), kernels::ResizeMode::bilinear_align_corners, flow_);
    // The image moves by τ, so output pixel p reads the input at p − τ.
    kernels::scale_shift(stream, flow_, -1.f, 0.f, flow_);
    kernels::warp(stream, x, flow_, warped_, kernels::SamplePadding::border);
  } else {
    kernels::fill(stream, flow_, 0.f);
    kernels::copy(stream, x, warped_);
  }
  mark(stream, &FrameStages::warp);
  if (!groups_.empty()) {
    blur(stream);
    kernels::copy(stream, blurred_, y);
  } else {
    kernels::copy(stream, warped_, y);
  }
  mark(stream, &FrameStages::blur);
  const SensorNoise& n = options_.noise;
  if (n.photons_per_unit > 0 || n.read_std > 0) {
    const float shot = n.photons_per_unit > 0 ? static_cast<float>(1 / n.photons_per_unit) : 0.f;
    kernels::sensor_noise(stream, y, y, shot, static_cast<float>(n.read_std), seed_ ^ kNoiseSalt,
                          static_cast<std::uint32_t>(frame_));
  }
  mark(stream, &FrameStages::noise);
}

void Simulator::frame(Stream& stream, const Tensor& x, const Tensor& y, FrameStages& stages) {
  stream.run();  // work recorded before the frame is not its own
  stages_ = &stages;
  stage_start_ = std::chrono::steady_clock::now();
  try {
    frame(stream, x, y);
  } catch (...) {
    stages_ = nullptr;
    throw;
  }
  stages_ = nullptr;
}

void Simulator::mark(Stream& stream, double FrameStages::*stage) {
  if (stages_ == nullptr) return;
  stream.run();
  const auto now = std::chrono::steady_clock::now();
  stages_->*stage += std::chrono::duration<double>(now - stage_start_).count();
  stage_start_ = now;
}

void Simulator::blur(Stream& stream) {
  std::vector<Tensor> outputs;
  for (BlurGroup& g : groups_) {
    if (!g.shares_beta) {
      g.model->weights(stream, field_->coefficients(), g.beta_grid, g.coefficient_scale);
      kernels::resize(stream, g.beta_grid, kernels::ResizeMode::bilinear_align_corners, g.beta);
    }
    mark(stream, &FrameStages::p2s);
    if (groups_.size() > 1) kernels::slice(stream, warped_, {.channel = g.first}, g.warped);
    if (g.fft) {
      g.fft->forward(stream, g.warped, g.beta, g.blurred, g.norm, {.normalize = true});
    } else {
      kernels::psf_conv(stream, g.warped, g.beta, g.model->basis(), g.blurred, g.norm,
                        {.normalize = true});
    }
    outputs.push_back(g.blurred);
    mark(stream, &FrameStages::blur);
  }
  if (groups_.size() > 1) kernels::concat_channels(stream, outputs, blurred_);
}

void Simulator::frame_backward(Stream& stream, const Tensor& dy, const Tensor& dx) {
  const char* op = "Simulator::frame_backward";
  if (frame_ < 0) throw InvalidArgument(op, "no frame has been simulated yet");
  const ImageShape& im = params_.image;
  const Shape shape{im.batch, im.channels, im.height, im.width};
  kernels::require_shape(dy, shape, op, "dy");
  kernels::require_shape(dx, shape, op, "dx");
  Tensor d_warped = dy;
  if (!groups_.empty()) {
    d_warped = Tensor::empty(device_, shape);
    std::vector<Tensor> parts;
    for (const BlurGroup& g : groups_) {
      Tensor dy_g = dy, d_warped_g = d_warped;
      if (groups_.size() > 1) {
        const Shape gs{im.batch, g.count, im.height, im.width};
        dy_g = Tensor::empty(device_, gs);
        d_warped_g = Tensor::empty(device_, gs);
        kernels::slice(stream, dy, {.channel = g.first}, dy_g);
        parts.push_back(d_warped_g);
      }
      const Tensor d_beta = Tensor::empty(device_, g.beta.shape());
      kernels::psf_conv_backward(stream, g.warped, g.beta, g.model->basis(), g.blurred, g.norm,
                                 dy_g, d_warped_g, d_beta, {.normalize = true});
    }
    if (groups_.size() > 1) kernels::concat_channels(stream, parts, d_warped);
  }
  if (options_.tilt) {
    kernels::warp_backward(stream, input_, flow_, d_warped, &dx, nullptr,
                           kernels::SamplePadding::border);
  } else {
    kernels::copy(stream, d_warped, dx);
  }
}

}  // namespace vkjr2::sim
