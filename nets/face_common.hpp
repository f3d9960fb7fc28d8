// Shared plumbing of the face-api models (TF.js weights → our layouts, model
// location, images to device tensors).
#pragma once

#include <vkjr2/nets/host_tensor.hpp>
#include <vkjr2/runtime/tensor.hpp>

#include <filesystem>

namespace vkjr2::nets {

// Where face-api's model/ folder is: $VKJR2_FACE_API_DIR, else
// ${VKJR2_CACHE_DIR:-$HOME/.cache/vkjr2}/face-api-1.7.15/model. Throws a
// clear error ("run scripts/setup") when the folder or `manifest` in it is
// missing.
std::filesystem::path face_api_model_dir();
std::filesystem::path face_api_manifest(const char* manifest);

// TF.js conv filter [kh, kw, cin, cout] (HWIO) → our OIHW [cout, cin, kh, kw].
Tensor conv_weight_from_hwio(const Device& device, const HostTensor& hwio, const char* name);
// TF.js depthwise filter [kh, kw, c, multiplier] → [c·multiplier, 1, kh, kw]
// (output channel c·multiplier + m, as TF orders them).
Tensor depthwise_weight_from_hwio(const Device& device, const HostTensor& hwio, const char* name);
// A 1-D tensor (bias, scale) of `expected` elements.
Tensor vector_from(const Device& device, const HostTensor& v, std::int64_t expected,
                   const char* name);

// HWC (or 1×HWC) float image → device tensor [1, C, H, W]; and back.
Tensor image_to_device(const Device& device, const HostTensor& hwc);
HostTensor image_to_host(const Tensor& nchw);  // first image of the batch, HWC

}  // namespace vkjr2::nets
