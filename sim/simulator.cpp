#include <vkjr2/kernels/basic.hpp>
#include <vkjr2/kernels/check.hpp>
#include <vkjr2/kernels/elementwise.hpp>
#include <vkjr2/kernels/psf_conv.hpp>
#include <vkjr2/kernels/random.hpp>
#include <vkjr2/kernels/resize.hpp>
#include <vkjr2/kernels/warp.hpp>
#include <vkjr2/runtime/error.hpp>
#include <vkjr2/sim/simulator.hpp>

#include <algorithm>
#include <cmath>
#include <string>

namespace vkjr2::sim {
namespace {

constexpr char kOp[] = "Simulator";
constexpr int kMaxPsfChannels = 4;  // psf_conv takes up to 4 channels per call
// Mixed into the seed for the sensor noise, so that it never repeats the
// turbulence seeds' numbers.
constexpr std::uint64_t kNoiseSalt = 0x9e3779b97f4a7c15ull;

// The relative sampling mismatch the blur model tolerates.
constexpr double kNyquistTolerance = 0.02;

}  // namespace

Simulator::~Simulator() = default;

Simulator::Simulator(const Device& device, const Params& params,
                     std::shared_ptr<const BlurModel> blur, const SimOptions& options)
    : device_(device),
      params_(params),
      derived_(derive(params)),
      options_(options),
      blur_(std::move(blur)) {
  if (options.blur) {
    if (!blur_) {
      throw InvalidArgument(kOp, "blur is on but no blur model (PSF basis + P2S network) was given",
                            "load one (vkjr2 sim-train makes it) or turn blur off");
    }
    if (blur_->j_max() > params.zernike_modes) {
      throw InvalidArgument(kOp,
                            "the blur model takes a_4..a_" + std::to_string(blur_->j_max()) +
                                " but the parameters simulate modes up to j = " +
                                std::to_string(params.zernike_modes),
                            "set zernike_modes to at least " + std::to_string(blur_->j_max()));
    }
    for (const ChannelDerived& c : derived_.channels) {
      if (std::fabs(c.nyquist / blur_->nyquist() - 1) > kNyquistTolerance) {
        throw InvalidArgument(kOp,
                              "the PSF basis was made for Nyquist ratio " +
                                  std::to_string(blur_->nyquist()) + " but the optics sample at " +
                                  std::to_string(c.nyquist) + " (λ f / (2 D p))",
                              "train a basis for these optics: vkjr2 sim-train --config FILE");
      }
    }
  }
  FieldOptions field_options = options.field;
  // Without blur only the tilts matter, and they allow a much coarser grid.
  if (!options.blur && field_options.j_max == 0) field_options.j_max = 3;
  if (options.blur && params.image.channels > kMaxPsfChannels) {
    throw InvalidArgument(
        kOp,
        "the blur takes 1 to 4 channels, the image has " + std::to_string(params.image.channels),
        "simulate the channels in groups of at most 4");
  }
  field_ = std::make_unique<TurbulenceField>(device_, params_, field_options);
  const ImageShape& im = params_.image;
  const std::int64_t b = im.batch, c = im.channels, h = im.height, w = im.width;
  flow_ = Tensor::empty(device_, {b, 2, h, w});
  warped_ = Tensor::empty(device_, {b, c, h, w});
  if (options.blur) {
    const std::int64_t k = blur_->basis().shape()[0];
    beta_grid_ = Tensor::empty(device_, {b, k, field_->grid_h(), field_->grid_w()});
    beta_ = Tensor::empty(device_, {b, k, h, w});
    norm_ = Tensor::empty(device_, {b, 1, h, w});
    blurred_ = Tensor::empty(device_, {b, c, h, w});
    const std::int64_t s = blur_->basis().shape()[1];
    if (kernels::psf_conv_path(b, c, k, s, h, w) == kernels::PsfConvPath::fft) {
      fft_ = std::make_unique<kernels::PsfConvFft>(device_, blur_->basis(), b, c, h, w);
    }
  }
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
  if (options_.tilt) {
    kernels::resize(stream, field_->tilt_px(), kernels::ResizeMode::bilinear_align_corners, flow_);
    // The image moves by τ, so output pixel p reads the input at p − τ.
    kernels::scale_shift(stream, flow_, -1.f, 0.f, flow_);
    kernels::warp(stream, x, flow_, warped_, kernels::SamplePadding::border);
  } else {
    kernels::fill(stream, flow_, 0.f);
    kernels::copy(stream, x, warped_);
  }
  if (options_.blur) {
    blur(stream, warped_, blurred_);
    kernels::copy(stream, blurred_, y);
  } else {
    kernels::copy(stream, warped_, y);
  }
  const SensorNoise& n = options_.noise;
  if (n.photons_per_unit > 0 || n.read_std > 0) {
    const float shot = n.photons_per_unit > 0 ? static_cast<float>(1 / n.photons_per_unit) : 0.f;
    kernels::sensor_noise(stream, y, y, shot, static_cast<float>(n.read_std), seed_ ^ kNoiseSalt,
                          static_cast<std::uint32_t>(frame_));
  }
}

void Simulator::blur(Stream& stream, const Tensor& x, const Tensor& y) {
  blur_->weights(stream, field_->coefficients(), beta_grid_);
  kernels::resize(stream, beta_grid_, kernels::ResizeMode::bilinear_align_corners, beta_);
  if (fft_) {
    fft_->forward(stream, x, beta_, y, norm_, {.normalize = true});
  } else {
    kernels::psf_conv(stream, x, beta_, blur_->basis(), y, norm_, {.normalize = true});
  }
}

void Simulator::frame_backward(Stream& stream, const Tensor& dy, const Tensor& dx) {
  if (frame_ < 0)
    throw InvalidArgument("Simulator::frame_backward", "no frame has been simulated yet");
  const ImageShape& im = params_.image;
  const Shape shape{im.batch, im.channels, im.height, im.width};
  kernels::require_shape(dy, shape, "Simulator::frame_backward", "dy");
  kernels::require_shape(dx, shape, "Simulator::frame_backward", "dx");
  Tensor d_warped = dy;
  if (options_.blur) {
    if (im.channels > kMaxPsfChannels) {
      throw InvalidArgument(
          "Simulator::frame_backward",
          "the blur's backward takes at most 4 channels, got " + std::to_string(im.channels));
    }
    d_warped = Tensor::empty(device_, shape);
    const Tensor d_beta = Tensor::empty(device_, beta_.shape());
    kernels::psf_conv_backward(stream, warped_, beta_, blur_->basis(), blurred_, norm_, dy,
                               d_warped, d_beta, {.normalize = true});
  }
  if (options_.tilt) {
    kernels::warp_backward(stream, input_, flow_, d_warped, &dx, nullptr,
                           kernels::SamplePadding::border);
  } else {
    kernels::copy(stream, d_warped, dx);
  }
}

}  // namespace vkjr2::sim
