// DeviceTraits: the tuning choices that depend on the device, in one table
// filled once per device from its driver, type and limits (like ncnn's
// per-driver flags). Kernels read their tile sizes, dispatch shapes and cost
// models from Device::traits() instead of constants measured on one driver.
//
// Two profiles exist today:
//  - "lavapipe": Mesa's CPU driver (llvmpipe), every value measured on it
//    (bench/RESULTS.md and the comments at each use; CONTRIBUTING.md has the
//    llvmpipe facts behind them).
//  - "gpu": every other device. Not measured (no GPU in the project's CI);
//    each value is the documented reasoning below, chosen so that a GPU is
//    never handed a CPU-specific shape (e.g. splitting small dispatches so
//    that each CPU thread gets a workgroup).
// VKJR2_DEVICE_TRAITS=lavapipe|gpu forces a profile on any device (the test
// suite runs the kernels under both on lavapipe against the same references
// and tolerances: a profile changes speed and rounding, not what is computed).
#pragma once

#include <cstdint>
#include <string>
#include <string_view>

namespace vkjr2 {

struct DeviceInfo;

struct DeviceTraits {
  std::string profile;    // "lavapipe" or "gpu"
  bool measured = false;  // the values were measured on this kind of device

  // ---- dispatch shape -------------------------------------------------------
  // group_lanes(): a small dispatch is split into workgroups of fewer lanes
  // (down to 8) until it has this many. llvmpipe runs one workgroup on one
  // thread, so 4 keeps both cores of a 2-core machine busy; a GPU wants full
  // workgroups (1: never split).
  std::uint32_t min_workgroups = 4;

  // ---- conv2d register tiles (kernels/conv2d.cpp) ---------------------------
  // Blocked kernel: a row of up to this many output pixels is one block.
  std::uint32_t conv_max_row_tile = 20;
  // Blocked kernel: vec4 accumulators per invocation (pixels × channel groups
  // × rows). llvmpipe keeps them on the stack, so large tiles win (fewer
  // weight fetches per FMA); a GPU keeps them in registers, where 25 vec4
  // (100 floats) costs occupancy: 16 (64 floats) there.
  std::uint32_t conv_max_tile_accumulators = 25;
  // Depthwise kernel: rows up to this wide are one block; px · ry float
  // accumulators per invocation.
  std::uint32_t depthwise_max_row_tile = 16;
  std::uint32_t depthwise_max_accumulators = 32;
  // Pointwise (1×1) kernel: 16 pixels per invocation (instead of 8) on planes
  // of at least this many pixels; 0 = never. Measured on lavapipe: faster on
  // 28² and 56² planes, slower on 14² and 7²; a GPU keeps the 8-pixel tile.
  std::uint64_t pointwise_wide_min_pixels = 512;

  // ---- memory movement -------------------------------------------------------
  // Elementwise binary ops read vec4 texels when the count and offsets allow
  // (llvmpipe: vector gathers, 4× the work per invocation).
  bool vec4_elementwise = true;
  // Whole-plane copies (concat, channel slices) go through vkCmdCopyBuffer,
  // one per image, up to this many images (lavapipe: 3–4× a shader copy);
  // above it, one shader dispatch.
  std::int64_t max_transfer_copies = 16;

  // ---- FFT and the PSF-basis convolution --------------------------------------
  // Largest radix of one FFT pass, as log2 (5: radix 32). Fewer passes won on
  // lavapipe (1024² c2c 1.5× faster at 2+2 passes than 3+3); a GPU's
  // registers favour radix ≤ 16 (4).
  std::uint32_t fft_max_log2_radix = 5;
  // psf_conv_path's cost model, seconds per unit: the direct path per
  // pixel-tap, the FFT path per (product image · padded point · log2 points).
  // lavapipe (256² RGB, K = 24, S = 21): direct 2.39 s = 3.4 ns per tap; FFT
  // 0.45 s = 3.7 ns per unit. Only their ratio matters; for a GPU the FFT's
  // memory passes cost relatively more than the direct path's FMAs, so the
  // ratio is taken 4× less favourable to the FFT.
  double psf_direct_seconds_per_tap = 3.4e-9;
  double psf_fft_seconds_per_point_log = 3.7e-9;
  // The FFT path's scratch may not exceed this; above it the direct path runs.
  std::int64_t psf_fft_max_temporary_bytes = std::int64_t{96} << 20;
};

// The measured lavapipe profile and the GPU default.
DeviceTraits lavapipe_traits();
DeviceTraits gpu_traits();

// The profile for a device: lavapipe's for Mesa's llvmpipe (driver id
// MESA_LLVMPIPE, or a CPU device named llvmpipe), else the GPU default.
// `override_profile` ("lavapipe" or "gpu"; empty: $VKJR2_DEVICE_TRAITS, else
// none) forces one; any other name is an InvalidArgument naming the choices.
DeviceTraits device_traits_for(const DeviceInfo& info, std::string_view override_profile = {});

}  // namespace vkjr2
