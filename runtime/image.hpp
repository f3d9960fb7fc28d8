// Images between the host and the device: the one place every command,
// benchmark and test converts a frame. On the host an image is H×W×C float
// (HostTensor [H, W, C] or [1, H, W, C], as decoders give it, 0..255 for
// 8-bit data); on the device it is NCHW planes.
#pragma once

#include <vkjr2/runtime/host_tensor.hpp>
#include <vkjr2/runtime/tensor.hpp>

#include <cstdint>
#include <span>
#include <vector>

namespace vkjr2 {

// CHW planes of an H×W×C image, each value divided by `range` (255 turns
// 8-bit values into 0..1; 1 keeps them). channels: 0 keeps C; 1 from an RGB
// image is the mean of R, G and B; 3 from a grey image repeats it. Throws
// InvalidArgument naming the shape for anything but an H×W×C image, or for
// a channel conversion other than these.
std::vector<float> image_to_planes(const HostTensor& hwc, int channels = 0, float range = 1.f);

// image_to_planes uploaded as [1, channels, H, W].
Tensor image_to_device(const Device& device, const HostTensor& hwc, int channels = 0,
                       float range = 1.f);

// CHW planes [channels, H, W] → an H×W×out_channels image: each value
// clamped to [0, 1] and multiplied by `range` when range > 0 (0..1 planes
// into 0..255 pixels), else copied as is; one plane into 3 channels repeats
// it. Throws InvalidArgument when the sizes disagree.
HostTensor planes_to_image(std::span<const float> planes, int channels, std::int64_t height,
                           std::int64_t width, int out_channels = 3, float range = 0.f);

// The first image of an NCHW device tensor as H×W×C (values as they are).
HostTensor image_to_host(const Tensor& nchw);

}  // namespace vkjr2
