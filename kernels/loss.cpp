#include <vkjr2/kernels/basic.hpp>
#include <vkjr2/kernels/check.hpp>
#include <vkjr2/kernels/loss.hpp>

#include <algorithm>
#include <string>

namespace vkjr2::kernels {
namespace {

constexpr std::uint32_t kReducePerGroup = 2048;  // loss_pointwise: 256 invocations × 8
constexpr std::uint32_t kPerGroup = 1024;        // loss_pointwise_grad: 256 × 4

struct PointwisePush {
  std::uint32_t n;
  float eps, inv_n;
};
struct RowsPush {
  std::uint32_t rows, k;
  float param;  // eps (cosine) or 1/rows (cross-entropy)
};
static_assert(sizeof(PointwisePush) <= 128 && sizeof(RowsPush) <= 128);

enum : std::uint32_t { kL1 = 0, kMse = 1, kCharbonnier = 2 };

void require_scalar(const Tensor& t, const char* op, const char* name) {
  if (require_f32(t, op, name) != 1) {
    throw InvalidArgument(
        op, std::string(name) + " must have exactly one element, got " + t.shape().str());
  }
}

void pointwise(Stream& stream, std::uint32_t kind, const char* op, const Tensor& pred,
               const Tensor& target, float eps, const Tensor& loss) {
  static const KernelDef k{"loss_pointwise",
                           {BindingKind::texel, BindingKind::texel, BindingKind::storage},
                           sizeof(PointwisePush)};
  const std::uint32_t n = require_f32(pred, op, "pred");
  require_f32(target, op, "target");
  require_same_shape(pred, target, op, "pred", "target");
  require_scalar(loss, op, "loss");
  require_subgroup_arithmetic(stream, op);
  const std::uint32_t groups = div_up(n, kReducePerGroup);
  const Tensor partial = groups == 1 ? loss : Tensor::empty(stream.device(), Shape{groups});
  stream.dispatch(k, {texel(pred), texel(target), out(partial)},
                  PointwisePush{n, eps, float(1.0 / double(n))},
                  groups_1d(groups, stream.device().info()), {kind});
  if (groups > 1) sum(stream, partial, loss);
}

void pointwise_backward(Stream& stream, std::uint32_t kind, const char* op, const Tensor& pred,
                        const Tensor& target, float eps, const Tensor& g, const Tensor& d_pred) {
  static const KernelDef k{
      "loss_pointwise_grad",
      {BindingKind::texel, BindingKind::texel, BindingKind::texel, BindingKind::storage},
      sizeof(PointwisePush)};
  const std::uint32_t n = require_f32(pred, op, "pred");
  require_f32(target, op, "target");
  require_same_shape(pred, target, op, "pred", "target");
  require_f32(d_pred, op, "d_pred");
  require_same_shape(pred, d_pred, op, "pred", "d_pred");
  require_scalar(g, op, "g");
  stream.dispatch(k, {texel(pred), texel(target), texel(g), out(d_pred)},
                  PointwisePush{n, eps, float(1.0 / double(n))},
                  groups_1d(div_up(n, kPerGroup), stream.device().info()), {kind});
}

void require_eps(float eps, const char* op) {
  if (!(eps > 0.f)) {
    throw InvalidArgument(op, "eps must be positive, got " + std::to_string(eps));
  }
}

// rows × k of a [..., k]; out has one element per row.
std::uint32_t rows_of(const Tensor& a, const Tensor& per_row, const char* op, const char* name) {
  const std::uint32_t n = require_f32(a, op, "a");
  const std::uint32_t rows = n / std::uint32_t(a.shape()[-1]);
  require_f32(per_row, op, name);
  if (per_row.numel() != std::int64_t(rows)) {
    throw InvalidArgument(op, std::string(name) + " " + per_row.shape().str() +
                                  " must have one element per row of " + a.shape().str() + " (" +
                                  std::to_string(rows) + ")");
  }
  return rows;
}

struct Classes {
  std::uint32_t rows, k;
};

Classes check_xent(const Tensor& logits, const Tensor& labels, const char* op) {
  require_f32_rank(logits, 2, op, "logits");
  const auto rows = std::uint32_t(logits.shape()[0]), k = std::uint32_t(logits.shape()[1]);
  if (!labels.defined() || labels.dtype() != DType::i32) {
    throw InvalidArgument(op, "labels must be an i32 tensor");
  }
  require_shape(labels, Shape{std::int64_t(rows)}, op, "labels (one class index per row)");
  return {rows, k};
}

}  // namespace

void l1_loss(Stream& stream, const Tensor& pred, const Tensor& target, const Tensor& loss) {
  pointwise(stream, kL1, "l1_loss", pred, target, 0.f, loss);
}
void l1_loss_backward(Stream& stream, const Tensor& pred, const Tensor& target, const Tensor& g,
                      const Tensor& d_pred) {
  pointwise_backward(stream, kL1, "l1_loss_backward", pred, target, 0.f, g, d_pred);
}
void mse_loss(Stream& stream, const Tensor& pred, const Tensor& target, const Tensor& loss) {
  pointwise(stream, kMse, "mse_loss", pred, target, 0.f, loss);
}
void mse_loss_backward(Stream& stream, const Tensor& pred, const Tensor& target, const Tensor& g,
                       const Tensor& d_pred) {
  pointwise_backward(stream, kMse, "mse_loss_backward", pred, target, 0.f, g, d_pred);
}
void charbonnier_loss(Stream& stream, const Tensor& pred, const Tensor& target, float eps,
                      const Tensor& loss) {
  require_eps(eps, "charbonnier_loss");
  pointwise(stream, kCharbonnier, "charbonnier_loss", pred, target, eps, loss);
}
void charbonnier_loss_backward(Stream& stream, const Tensor& pred, const Tensor& target, float eps,
                               const Tensor& g, const Tensor& d_pred) {
  require_eps(eps, "charbonnier_loss_backward");
  pointwise_backward(stream, kCharbonnier, "charbonnier_loss_backward", pred, target, eps, g,
                     d_pred);
}

void cosine_similarity(Stream& stream, const Tensor& a, const Tensor& b, const Tensor& y,
                       float eps) {
  static const KernelDef k{"loss_cosine",
                           {BindingKind::texel, BindingKind::texel, BindingKind::storage},
                           sizeof(RowsPush)};
  const char* op = "cosine_similarity";
  require_eps(eps, op);
  const std::uint32_t rows = rows_of(a, y, op, "y");
  require_f32(b, op, "b");
  require_same_shape(a, b, op, "a", "b");
  const auto len = std::uint32_t(a.shape()[-1]);
  stream.dispatch(k, {texel(a), texel(b), out(y)}, RowsPush{rows, len, eps},
                  subgroup_row_groups(stream, rows, op));
}

void cosine_similarity_backward(Stream& stream, const Tensor& a, const Tensor& b, const Tensor& dy,
                                const Tensor& da, const Tensor& db, float eps) {
  static const KernelDef k{"loss_cosine_grad",
                           {BindingKind::texel, BindingKind::texel, BindingKind::texel,
                            BindingKind::storage, BindingKind::storage},
                           sizeof(RowsPush)};
  const char* op = "cosine_similarity_backward";
  require_eps(eps, op);
  const std::uint32_t rows = rows_of(a, dy, op, "dy");
  require_f32(b, op, "b");
  require_same_shape(a, b, op, "a", "b");
  require_f32(da, op, "da");
  require_same_shape(a, da, op, "a", "da");
  require_f32(db, op, "db");
  require_same_shape(a, db, op, "a", "db");
  const auto len = std::uint32_t(a.shape()[-1]);
  stream.dispatch(k, {texel(a), texel(b), texel(dy), out(da), out(db)}, RowsPush{rows, len, eps},
                  subgroup_row_groups(stream, rows, op));
}

void cross_entropy(Stream& stream, const Tensor& logits, const Tensor& labels, const Tensor& loss) {
  static const KernelDef k{"loss_xent",
                           {BindingKind::texel, BindingKind::texel, BindingKind::storage},
                           sizeof(RowsPush)};
  const char* op = "cross_entropy";
  const Classes c = check_xent(logits, labels, op);
  require_scalar(loss, op, "loss");
  const Tensor per_row = c.rows == 1 ? loss : Tensor::empty(stream.device(), Shape{c.rows});
  stream.dispatch(k, {texel(logits), texel(labels, VK_FORMAT_R32_SINT), out(per_row)},
                  RowsPush{c.rows, c.k, float(1.0 / double(c.rows))},
                  subgroup_row_groups(stream, c.rows, op));
  if (c.rows > 1) sum(stream, per_row, loss);
}

void cross_entropy_backward(Stream& stream, const Tensor& logits, const Tensor& labels,
                            const Tensor& g, const Tensor& d_logits) {
  static const KernelDef k{
      "loss_xent_grad",
      {BindingKind::texel, BindingKind::texel, BindingKind::texel, BindingKind::storage},
      sizeof(RowsPush)};
  const char* op = "cross_entropy_backward";
  const Classes c = check_xent(logits, labels, op);
  require_scalar(g, op, "g");
  require_f32(d_logits, op, "d_logits");
  require_same_shape(logits, d_logits, op, "logits", "d_logits");
  stream.dispatch(k, {texel(logits), texel(labels, VK_FORMAT_R32_SINT), texel(g), out(d_logits)},
                  RowsPush{c.rows, c.k, float(1.0 / double(c.rows))},
                  subgroup_row_groups(stream, c.rows, op));
}

}  // namespace vkjr2::kernels
