// A face clip with context, as the JR² benchmark cuts it (vkjr2 dataset make,
// vkjr2 bench pipeline): the image scaled so that the face box is face_px
// wide, a clip_size² window centred on the face, edges replicated past the
// image (docs/eval.md §1).
#pragma once

#include <vkjr2/nets/face_box.hpp>
#include <vkjr2/runtime/host_tensor.hpp>

namespace vkjr2::cli {

// img: H×W×3 RGB float 0..255 → clip_size×clip_size×3, clamped to 0..255.
// Down-scaling averages areas, up-scaling is bicubic.
vkjr2::HostTensor face_clip(const vkjr2::HostTensor& img, const nets::FaceBox& box, int clip_size,
                            int face_px);

}  // namespace vkjr2::cli
