#include <vkjr2/kernels/ref/layout_ref.hpp>

namespace vkjr2::ref {

std::vector<float> pad(std::span<const float> x, Nchw s, const kernels::Pad2d& p, float value) {
  const std::int64_t h = s.h + p.top + p.bottom, w = s.w + p.left + p.right;
  std::vector<float> y(static_cast<std::size_t>(s.n * s.c * h * w), value);
  for (std::int64_t nc = 0; nc < s.n * s.c; ++nc) {
    for (std::int64_t i = 0; i < s.h; ++i) {
      for (std::int64_t j = 0; j < s.w; ++j) {
        y[static_cast<std::size_t>((nc * h + i + p.top) * w + j + p.left)] =
            x[static_cast<std::size_t>((nc * s.h + i) * s.w + j)];
      }
    }
  }
  return y;
}

std::vector<float> slice(std::span<const float> x, Nchw s, const kernels::SliceStart& at, Nchw o) {
  std::vector<float> y(static_cast<std::size_t>(o.numel()));
  std::size_t k = 0;
  for (std::int64_t n = 0; n < o.n; ++n) {
    for (std::int64_t c = 0; c < o.c; ++c) {
      for (std::int64_t i = 0; i < o.h; ++i) {
        for (std::int64_t j = 0; j < o.w; ++j) {
          y[k++] = x[static_cast<std::size_t>(
              ((n * s.c + c + at.channel) * s.h + i + at.row) * s.w + j + at.col)];
        }
      }
    }
  }
  return y;
}

std::vector<float> concat_channels(std::span<const std::vector<float>> xs,
                                   std::span<const Nchw> shapes) {
  std::vector<float> y;
  const std::int64_t batch = shapes[0].n;
  for (std::int64_t n = 0; n < batch; ++n) {
    for (std::size_t k = 0; k < xs.size(); ++k) {
      const std::int64_t per = shapes[k].c * shapes[k].h * shapes[k].w;
      y.insert(y.end(), xs[k].begin() + n * per, xs[k].begin() + (n + 1) * per);
    }
  }
  return y;
}

std::vector<float> channel_affine(std::span<const float> x, Nchw s, std::span<const float> scale,
                                  std::span<const float> bias) {
  std::vector<float> y(x.size());
  for (std::size_t i = 0; i < x.size(); ++i) {
    const auto c = static_cast<std::size_t>((std::int64_t(i) / (s.h * s.w)) % s.c);
    y[i] = x[i] * scale[c] + bias[c];
  }
  return y;
}

void channel_affine_backward(std::span<const float> x, Nchw s, std::span<const float> scale,
                             std::span<const float> dy, std::vector<float>& dx,
                             std::vector<float>& dscale, std::vector<float>& dbias) {
  dx.resize(x.size());
  std::vector<double> ds(static_cast<std::size_t>(s.c)), db(static_cast<std::size_t>(s.c));
  for (std::size_t i = 0; i < x.size(); ++i) {
    const auto c = static_cast<std::size_t>((std::int64_t(i) / (s.h * s.w)) % s.c);
    dx[i] = dy[i] * scale[c];
    ds[c] += double(dy[i]) * x[i];
    db[c] += dy[i];
  }
  dscale.assign(ds.begin(), ds.end());
  dbias.assign(db.begin(), db.end());
}

namespace {

// Index in small [n, c·r², h, w] and in big [n, c, h·r, w·r] of each element.
template <class F>
void for_each_shuffled(Nchw small, int r, F f) {
  const std::int64_t c = small.c / (r * r), bh = small.h * r, bw = small.w * r;
  for (std::int64_t n = 0; n < small.n; ++n)
    for (std::int64_t k = 0; k < c; ++k)
      for (std::int64_t y = 0; y < bh; ++y)
        for (std::int64_t x = 0; x < bw; ++x) {
          const std::int64_t ch = (k * r + y % r) * r + x % r;
          const std::int64_t si = ((n * small.c + ch) * small.h + y / r) * small.w + x / r;
          const std::int64_t bi = ((n * c + k) * bh + y) * bw + x;
          f(static_cast<std::size_t>(si), static_cast<std::size_t>(bi));
        }
}

}  // namespace

std::vector<float> flip_spatial(std::span<const float> x, Nchw s) {
  std::vector<float> y(x.size());
  for (std::int64_t p = 0; p < s.n * s.c; ++p) {
    for (std::int64_t i = 0; i < s.h; ++i) {
      for (std::int64_t j = 0; j < s.w; ++j) {
        y[std::size_t((p * s.h + i) * s.w + j)] =
            x[std::size_t((p * s.h + (s.h - 1 - i)) * s.w + (s.w - 1 - j))];
      }
    }
  }
  return y;
}

std::vector<float> pixel_shuffle(std::span<const float> x, Nchw small, int r) {
  std::vector<float> y(x.size());
  for_each_shuffled(small, r, [&](std::size_t si, std::size_t bi) { y[bi] = x[si]; });
  return y;
}

std::vector<float> pixel_unshuffle(std::span<const float> big, Nchw small, int r) {
  std::vector<float> y(big.size());
  for_each_shuffled(small, r, [&](std::size_t si, std::size_t bi) { y[si] = big[bi]; });
  return y;
}

}  // namespace vkjr2::ref
