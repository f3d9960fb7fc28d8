// One probe video through one method of the JR² evaluation: what
// `vkjr2 eval` runs per probe and `vkjr2 gate train` labels the gate with.
//
// Methods: degraded (the frames as the camera gave them), classical (temporal
// mean + unsharp mask), restored:MODEL (the restorer on the T frames around
// each sampled frame; an align-first model restores aligned crops) and
// gated:MODEL,GATE (the degraded probe's features decide whether MODEL runs).
#pragma once

#include <vkjr2/jr2/faces.hpp>
#include <vkjr2/jr2/gate.hpp>
#include <vkjr2/jr2/protocol.hpp>
#include <vkjr2/jr2/restorer.hpp>
#include <vkjr2/jr2/turbulence.hpp>
#include <vkjr2/runtime/device.hpp>
#include <vkjr2/runtime/host_tensor.hpp>

#include <cstdint>
#include <filesystem>
#include <memory>
#include <optional>
#include <string>
#include <vector>

namespace vkjr2::cli {

struct Method {
  std::string name;                         // as reported ("restored:restorer_default")
  std::unique_ptr<jr2::Restorer> restorer;  // restored:MODEL, gated:MODEL,GATE
  std::unique_ptr<jr2::Gate> gate;          // gated:MODEL,GATE
  bool classical = false;
  bool align_first = false;  // a `vkjr2 cotrain --order align-first` model: restores aligned crops
};

// The model files a method's text names (none for degraded and classical),
// checked before any work; throws UsageError (--method) naming the fault.
std::vector<std::filesystem::path> check_method(const std::string& text);
Method load_method(const Device& device, const std::string& text);

// The gate's features read the estimated D/r0 (vkjr2 estimate's DIS
// registration with the shipped calibration and the benchmark's optics)
// and the features of the alignment the gate was trained with.
struct GateContext {
  sim::Params optics;
  jr2::TurbulenceCalibration calibration;
  int align_index = 0;  // in ProtocolOptions::aligns
};
// The shipped calibration and the optics `vkjr2 dataset make` simulates with
// (jr2::probe_sim_params: the moderate preset); align_index of `align` in the protocol
// (UsageError naming --align when it is not evaluated).
GateContext gate_context(const jr2::ProtocolOptions& protocol, jr2::AlignMode align);

struct ProbeContext {
  const Device& device;
  Stream& stream;
  const jr2::FaceAnalyzer& analyzer;
  const jr2::ProbePipeline& pipeline;
  jr2::ClassicalOptions classical;
  const GateContext* gate = nullptr;  // needed by gated methods
};

// One probe video, decoded (read_probe_video in media.hpp reads one from
// its files), and its clean clip.
class ProbeVideo {
 public:
  // frames: H×W×3, 0..255; clean: [1, 3, H, W] on the device, 0..255
  // (clean_path names it in errors).
  ProbeVideo(const Device& device, std::vector<HostTensor> frames, Tensor clean,
             std::filesystem::path clean_path, std::uint64_t sampler_seed);
  const std::vector<HostTensor>& frames() const { return frames_; }
  const Tensor& clean() const { return clean_; }
  std::uint64_t sampler_seed() const { return seed_; }
  const std::filesystem::path& clean_path() const { return clean_path_; }
  // Frame i on the device as 0..1 (uploaded once).
  const Tensor& unit_frame(std::size_t i);
  // D/r0 estimated from every frame (computed once).
  double d_over_r0(const GateContext& g);

 private:
  const Device& device_;
  std::vector<HostTensor> frames_;
  std::vector<Tensor> unit_;
  Tensor clean_;
  std::filesystem::path clean_path_;
  std::uint64_t seed_;
  std::optional<double> d_over_r0_;
};

struct MethodRun {
  jr2::ProbeOutcome outcome;
  jr2::ClipQuality quality;
  double seconds = 0;  // wall time of the method on this probe (decoding excluded)
  // Gated methods: the gate's reading and whether it restored.
  std::optional<jr2::GatePrediction> gate;
};

MethodRun run_method(ProbeContext& ctx, const Method& method, ProbeVideo& video);

// The gate's features of a degraded probe run.
jr2::GateFeatures gate_features(ProbeContext& ctx, ProbeVideo& video,
                                const jr2::ProbeOutcome& degraded);

}  // namespace vkjr2::cli
