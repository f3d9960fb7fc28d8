#include <vkjr2/kernels/ref/mix_ref.hpp>

namespace vkjr2::ref {

void mix_planes(std::span<const float> planes, std::int64_t plane_h, std::int64_t plane_w,
                std::span<const float> mix, std::int64_t k, const kernels::MixPlanesParams& p,
                std::vector<float>& out, std::vector<float>& first2) {
  const std::int64_t points = p.out_h * p.out_w;
  out.assign(std::size_t(p.batch * points * k), 0.f);
  first2.assign(std::size_t(p.batch * 2 * points), 0.f);
  for (std::int64_t b = 0; b < p.batch; ++b) {
    for (std::int64_t y = 0; y < p.out_h; ++y) {
      for (std::int64_t x = 0; x < p.out_w; ++x) {
        const std::int64_t pt = y * p.out_w + x;
        for (std::int64_t i = 0; i < k; ++i) {
          double acc = 0;
          for (std::int64_t kk = 0; kk < k; ++kk) {
            const std::int64_t plane = kk * p.batch + b;
            acc += double(mix[std::size_t(i * k + kk)]) *
                   planes[std::size_t(((plane * plane_h + y) * plane_w + x) * 2)];
          }
          const float v = static_cast<float>(acc * p.scale);
          out[std::size_t((b * k + i) * points + pt)] = v;
          if (i < 2)
            first2[std::size_t((b * 2 + i) * points + pt)] = v * p.first2_scale[std::size_t(i)];
        }
      }
    }
  }
}

}  // namespace vkjr2::ref
