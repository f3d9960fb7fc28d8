// How an NCHW activation is stored between kernels: plain (the contiguous
// tensor [N, C, H, W]) or padded: each of the N·C planes is hp × wp with the
// image at (top, left) and zeros around it. A convolution whose variant reads
// a zero-bordered input (Conv2dPlan::input_layout) reads padded planes with
// no padding pass, so the kernel that produces its input (a convolution, a
// max pool, the network-input resize) writes straight into them. A strided
// convolution's layout may stop short of the image's last rows or columns,
// which it never reads: a convolution writing into such planes leaves them
// out (the pool and the resize need planes that hold the whole image).
#pragma once

#include <vkjr2/runtime/stream.hpp>

#include <cstdint>
#include <string>

namespace vkjr2::kernels {

struct PlaneLayout {
  std::uint32_t hp = 0, wp = 0;  // 0 × 0: plain
  std::int32_t top = 0, left = 0;
  bool plain() const noexcept { return hp == 0 && wp == 0; }
  bool operator==(const PlaneLayout&) const = default;
  std::string str() const;  // "plain" or "hp×wp at (top, left)"
};

struct Planes {
  Tensor data;  // plain: the tensor [N, C, H, W]; padded: [N·C·hp·wp]
  Shape shape;  // the image's [N, C, H, W]
  PlaneLayout layout;

  bool defined() const noexcept { return data.defined(); }
  bool padded() const noexcept { return !layout.plain(); }
  // Where the image lies in data: the layout, or H × W at (0, 0) when plain.
  PlaneLayout geometry() const noexcept;

  // A plain tensor [N, C, H, W] as planes (shares its memory).
  static Planes of(const Tensor& x);
  // New planes of shape [N, C, H, W] in `layout`: plain ones uninitialized,
  // padded ones zero-filled on `stream` (the border must read as zeros).
  // InvalidArgument for a shape that is not 4-D or a negative offset.
  static Planes make(Stream& stream, const Shape& shape, const PlaneLayout& layout);
};

// Whether `layout` holds the whole image of shape [N, C, H, W]; empty when
// it does, else why not (for error messages).
std::string layout_misfit(const Shape& shape, const PlaneLayout& layout);

// The image as a plain tensor: x.data itself when plain, else a copy of the
// interior recorded on `stream` (InvalidArgument when the planes leave part
// of it out).
Tensor unpad(Stream& stream, const Planes& x);

}  // namespace vkjr2::kernels
