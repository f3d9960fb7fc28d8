// The fast turbulence simulator: one degraded frame per call,
//   y = Σ_k ψ_k ⊛ (β_k ⊙ W(x; τ)) / Σ_k ψ_k ⊛ β_k + noise        (DESIGN.md, "Frame formation")
// with the tilt field τ (pixels, from a_2, a_3) warping the image, the
// PSF-basis weights β_k from the high-order coefficients a_4..a_J through
// a BlurModel (the P2S network), both on the coarse grid of a
// TurbulenceField and bilinearly interpolated to every pixel, and optional
// Poisson–Gaussian sensor noise. Everything is recorded into a Stream;
// frame t + 1's turbulence is frame t's AR(1) successor (video).
// Differentiable with respect to the input image (frame_backward).
#pragma once

#include <vkjr2/kernels/psf_conv.hpp>
#include <vkjr2/runtime/stream.hpp>
#include <vkjr2/sim/blur_model.hpp>
#include <vkjr2/sim/field.hpp>
#include <vkjr2/sim/params.hpp>

#include <chrono>
#include <cstdint>
#include <memory>
#include <vector>

namespace vkjr2::sim {

struct SensorNoise {
  double photons_per_unit = 0;  // shot noise: photons for a pixel value of 1 (0 = none)
  double read_std = 0;          // read noise σ in pixel-value units
};

// Where a frame's time goes (Simulator::frame with a FrameStages): wall
// seconds of each stage, the stream run after each so that none overlaps
// the next. Accumulated over the frames it is passed to.
struct FrameStages {
  double fields = 0;  // the turbulence field's next state (Zernike modes, tilt)
  double warp = 0;    // tilt → flow, the warp
  double p2s = 0;     // blur-basis weights β from the field (P2S), resized to the frame
  double blur = 0;    // the PSF-basis convolution (and channel slices / concat)
  double noise = 0;   // sensor noise
  double total() const { return fields + warp + p2s + blur + noise; }
};

struct SimOptions {
  FieldOptions field;
  bool tilt = true;
  bool blur = true;  // needs a BlurModel
  SensorNoise noise;
};

class Simulator {
 public:
  // params.image gives the frame shape [batch, channels, height, width].
  // blur may be null when options.blur is false. Throws InvalidArgument when
  // the blur model's sampling or modes do not fit the parameters.
  Simulator(const Device& device, const Params& params, std::shared_ptr<const BlurModel> blur,
            const SimOptions& options = {});
  // One blur model per distinct channel sampling: channel c blurs with the
  // first model whose Nyquist ratio matches λ_c f / (2 D p), its
  // coefficients scaled by λ_0/λ_c (phase at its own wavelength; the tilt is
  // achromatic and shared). Models may be listed that no channel uses; a
  // channel that none fits is an InvalidArgument naming it and the fix.
  Simulator(const Device& device, const Params& params,
            std::vector<std::shared_ptr<const BlurModel>> blur_models,
            const SimOptions& options = {});
  ~Simulator();
  Simulator(const Simulator&) = delete;
  Simulator& operator=(const Simulator&) = delete;

  // A new sequence from this seed (turbulence and noise).
  void reset(std::uint64_t seed);
  // Records the next frame: x, y [B, C, H, W] (y may not alias x).
  void frame(Stream& stream, const Tensor& x, const Tensor& y);
  // The same frame, run stage by stage with each stage's wall time added to
  // `stages` (for profiling: the stream is run after every stage).
  void frame(Stream& stream, const Tensor& x, const Tensor& y, FrameStages& stages);
  // dx = ∂⟨dy, y⟩/∂x for the last frame's turbulence (noise is additive).
  void frame_backward(Stream& stream, const Tensor& dy, const Tensor& dx);

  const Params& params() const { return params_; }
  const Derived& derived() const { return derived_; }
  const TurbulenceField& field() const { return *field_; }
  // The last frame's maps: flow [B, 2, H, W] (the warp's sampling offset,
  // = −tilt), beta [B, K, H, W] of channel 0 (undefined without blur).
  const Tensor& flow() const { return flow_; }
  const Tensor& beta() const { return beta(0); }
  // Channel c's β maps (channels that share a blur group share them).
  const Tensor& beta(int channel) const;
  // The blur model channel c uses (null without blur).
  const BlurModel* blur_model(int channel) const;

 private:
  // A run of consecutive channels (at most 4) that blur with one model.
  struct BlurGroup {
    int first = 0, count = 0;
    std::shared_ptr<const BlurModel> model;
    float coefficient_scale = 1;  // λ_0 / λ_c
    bool shares_beta = false;     // an earlier group with this model and scale makes beta
    std::unique_ptr<kernels::PsfConvFft> fft;  // the FFT path, when it is the cheaper one
    // beta_grid [B, K, gh, gw], beta [B, K, H, W], norm [B, 1, H, W]; with
    // more than one group also the group's warped and blurred channels
    // [B, count, H, W] (with one group these are the whole frame's).
    Tensor beta_grid, beta, norm, warped, blurred;
  };
  void blur(Stream& stream);
  // With stages_ set (the profiling frame()): runs the stream and adds the
  // time since the last mark to that stage.
  void mark(Stream& stream, double FrameStages::*stage);
  const BlurGroup& group_of(int channel) const;
  Device device_;
  Params params_;
  Derived derived_;
  SimOptions options_;
  std::vector<BlurGroup> groups_;
  std::unique_ptr<TurbulenceField> field_;
  std::uint64_t seed_ = 0;
  std::int64_t frame_ = -1;
  FrameStages* stages_ = nullptr;
  std::chrono::steady_clock::time_point stage_start_;
  Tensor input_;  // the last frame's x (its backward needs it)
  Tensor flow_, warped_, blurred_;
};

}  // namespace vkjr2::sim
