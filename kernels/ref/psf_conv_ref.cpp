#include <vkjr2/kernels/ref/psf_conv_ref.hpp>

namespace vkjr2::ref {

void psf_conv(const PsfConvDims& d, const std::vector<float>& x, const std::vector<float>& beta,
              const std::vector<float>& psi, bool normalize, std::vector<float>& y,
              std::vector<float>& norm) {
  const int plane = d.h * d.w;
  const int r = d.s / 2;
  y.assign(std::size_t(d.n) * d.c * plane, 0.f);
  norm.assign(std::size_t(d.n) * plane, 0.f);
  for (int n = 0; n < d.n; ++n) {
    // A_c = Σ_k ψ_k ⊛ (β_k x_c), B = Σ_k ψ_k ⊛ β_k.
    std::vector<double> a(std::size_t(d.c) * plane, 0.0), b(std::size_t(plane), 0.0);
    for (int k = 0; k < d.k; ++k) {
      const float* bk = &beta[(std::size_t(n) * d.k + k) * plane];
      const float* pk = &psi[std::size_t(k) * d.s * d.s];
      for (int py = 0; py < d.h; ++py) {
        for (int px = 0; px < d.w; ++px) {
          for (int qy = -r; qy <= r; ++qy) {
            for (int qx = -r; qx <= r; ++qx) {
              const int sy = py - qy, sx = px - qx;
              if (sy < 0 || sy >= d.h || sx < 0 || sx >= d.w) continue;
              const double w = double(pk[(qy + r) * d.s + (qx + r)]) * bk[sy * d.w + sx];
              b[py * d.w + px] += w;
              for (int c = 0; c < d.c; ++c) {
                a[std::size_t(c) * plane + py * d.w + px] +=
                    w * x[(std::size_t(n) * d.c + c) * plane + sy * d.w + sx];
              }
            }
          }
        }
      }
    }
    for (int p = 0; p < plane; ++p) {
      norm[std::size_t(n) * plane + p] = float(b[p]);
      for (int c = 0; c < d.c; ++c) {
        const double v = a[std::size_t(c) * plane + p];
        y[(std::size_t(n) * d.c + c) * plane + p] = float(normalize ? v / b[p] : v);
      }
    }
  }
}

}  // namespace vkjr2::ref
