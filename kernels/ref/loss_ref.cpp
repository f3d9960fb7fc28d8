#include <vkjr2/kernels/ref/loss_ref.hpp>
#include <vkjr2/kernels/ref/softmax_ref.hpp>

#include <algorithm>
#include <cmath>

namespace vkjr2::ref {

double pointwise_loss(int kind, std::span<const float> pred, std::span<const float> target,
                      float eps) {
  double s = 0;
  for (std::size_t i = 0; i < pred.size(); ++i) {
    const double d = double(pred[i]) - target[i];
    s += kind == 0 ? std::fabs(d) : (kind == 1 ? d * d : std::sqrt(d * d + double(eps) * eps));
  }
  return s / double(pred.size());
}

std::vector<float> pointwise_loss_backward(int kind, std::span<const float> pred,
                                           std::span<const float> target, float eps, float g) {
  std::vector<float> dp(pred.size());
  const double scale = double(g) / double(pred.size());
  for (std::size_t i = 0; i < pred.size(); ++i) {
    const double d = double(pred[i]) - target[i];
    const double r = kind == 0 ? (d > 0) - (d < 0)
                               : (kind == 1 ? 2 * d : d / std::sqrt(d * d + double(eps) * eps));
    dp[i] = float(scale * r);
  }
  return dp;
}

namespace {
struct CosineRow {
  double dot = 0, na = 0, nb = 0;
};
CosineRow cosine_row(std::span<const float> a, std::span<const float> b, std::size_t base,
                     std::size_t k) {
  CosineRow r;
  for (std::size_t j = 0; j < k; ++j) {
    const double u = a[base + j], v = b[base + j];
    r.dot += u * v;
    r.na += u * u;
    r.nb += v * v;
  }
  r.na = std::sqrt(r.na);
  r.nb = std::sqrt(r.nb);
  return r;
}
}  // namespace

std::vector<float> cosine_similarity(std::span<const float> a, std::span<const float> b,
                                     std::size_t k, float eps) {
  std::vector<float> y(a.size() / k);
  for (std::size_t r = 0; r < y.size(); ++r) {
    const CosineRow c = cosine_row(a, b, r * k, k);
    y[r] = float(c.dot / (std::max(c.na, double(eps)) * std::max(c.nb, double(eps))));
  }
  return y;
}

void cosine_similarity_backward(std::span<const float> a, std::span<const float> b,
                                std::span<const float> dy, std::size_t k, float eps,
                                std::vector<float>& da, std::vector<float>& db) {
  da.assign(a.size(), 0.f);
  db.assign(a.size(), 0.f);
  for (std::size_t r = 0; r < a.size() / k; ++r) {
    const CosineRow c = cosine_row(a, b, r * k, k);
    const double ua = std::max(c.na, double(eps)), ub = std::max(c.nb, double(eps));
    const double cs = c.dot / (ua * ub);
    const double ka = c.na > eps ? cs / (ua * ua) : 0, kb = c.nb > eps ? cs / (ub * ub) : 0;
    for (std::size_t j = 0; j < k; ++j) {
      const std::size_t i = r * k + j;
      da[i] = float(dy[r] * (b[i] / (ua * ub) - ka * a[i]));
      db[i] = float(dy[r] * (a[i] / (ua * ub) - kb * b[i]));
    }
  }
}

double cross_entropy(std::span<const float> logits, std::span<const std::int32_t> labels,
                     std::size_t k) {
  const std::vector<float> ls = softmax(logits, k, true);
  double s = 0;
  for (std::size_t r = 0; r < labels.size(); ++r) s -= ls[r * k + std::size_t(labels[r])];
  return s / double(labels.size());
}

std::vector<float> cross_entropy_backward(std::span<const float> logits,
                                          std::span<const std::int32_t> labels, std::size_t k,
                                          float g) {
  std::vector<float> d = softmax(logits, k, false);
  for (std::size_t r = 0; r < labels.size(); ++r) {
    for (std::size_t j = 0; j < k; ++j) {
      const double onehot = std::int32_t(j) == labels[r] ? 1.0 : 0.0;
      d[r * k + j] = float(double(g) / double(labels.size()) * (d[r * k + j] - onehot));
    }
  }
  return d;
}

}  // namespace vkjr2::ref
