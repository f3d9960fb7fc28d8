// Pooling over NCHW images: max (with argmax indices for the backward),
// average and global average, forward and backward.
#pragma once

#include <vkjr2/kernels/planes.hpp>
#include <vkjr2/runtime/stream.hpp>

#include <cstdint>

namespace vkjr2::kernels {

// Window, stride and explicit asymmetric zero-extent padding of a 2-D pool.
// Output size per axis (floor mode): (in + pad_before + pad_after − kernel) / stride + 1.
// Each padding side must be smaller than the kernel on its axis, so that every
// window holds at least one input pixel.
struct Pool2d {
  std::int32_t kernel_h = 2, kernel_w = 2;
  std::int32_t stride_h = 2, stride_w = 2;
  std::int32_t pad_top = 0, pad_bottom = 0, pad_left = 0, pad_right = 0;
};

// TensorFlow "SAME" padding: output = ceil(in / stride), the padding total
// max((out − 1)·stride + kernel − in, 0) split with the extra pixel at the
// bottom/right (as TF and face-api do).
Pool2d pool_same(std::int32_t kernel_h, std::int32_t kernel_w, std::int32_t stride_h,
                 std::int32_t stride_w, std::int64_t in_h, std::int64_t in_w);
// TensorFlow "VALID" (no padding).
Pool2d pool_valid(std::int32_t kernel_h, std::int32_t kernel_w, std::int32_t stride_h,
                  std::int32_t stride_w);

// [N, C, OH, OW] for x of shape [N, C, H, W]; throws InvalidArgument on a bad
// configuration (non-positive kernel/stride, padding ≥ kernel, empty output).
Shape pool_output_shape(const Shape& x, const Pool2d& p);

// Max pool. Padding taps never win (they act as −inf). y: [N, C, OH, OW];
// indices: same shape, i32, the flat index h·W + w of the maximum inside its
// input plane (first maximum in row-major window order on ties). NaN
// propagates as in PyTorch: a window holding a NaN outputs NaN, and its index
// is that of the last NaN. indices may be undefined (inference: not written).
void max_pool2d(Stream& stream, const Tensor& x, const Pool2d& p, const Tensor& y,
                const Tensor& indices);
// max_pool2d with y written into the interior of a conv's zero-padded input
// (padded planes in the layout of the conv that reads the pool's output:
// Conv2dPlan::input_layout; no indices), so that conv
// needs no padding pass.
void max_pool2d_into_padded(Stream& stream, const Tensor& x, const Pool2d& p, const Planes& y);
// dx[n,c,h,w] = Σ dy over the windows whose saved index is (h, w). Written as
// a gather over the windows covering each input pixel: deterministic, dx fully
// overwritten. dx: [N, C, H, W] (the input's shape).
void max_pool2d_backward(Stream& stream, const Tensor& dy, const Tensor& indices, const Pool2d& p,
                         const Tensor& dx);

// Average pool. count_include_pad = false divides by the number of input
// pixels inside the window (TensorFlow / face-api avg_pool with SAME padding);
// true divides by the window area clipped to the padded image (PyTorch's
// default count_include_pad=True). Both agree when there is no padding.
void avg_pool2d(Stream& stream, const Tensor& x, const Pool2d& p, bool count_include_pad,
                const Tensor& y);
// dx[h, w] = Σ over the windows covering (h, w) of dy / divisor (gather).
void avg_pool2d_backward(Stream& stream, const Tensor& dy, const Pool2d& p, bool count_include_pad,
                         const Tensor& dx);

// y[n, c] = mean over H×W of x[n, c]. x: [N, C, H, W], y: [N, C, 1, 1].
// Fixed-order reduction: deterministic.
void global_avg_pool(Stream& stream, const Tensor& x, const Tensor& y);
// dx[n, c, h, w] = dy[n, c] / (H·W). dy: [N, C, 1, 1], dx: [N, C, H, W].
void global_avg_pool_backward(Stream& stream, const Tensor& dy, const Tensor& dx);

}  // namespace vkjr2::kernels
