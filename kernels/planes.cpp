#include <vkjr2/kernels/check.hpp>
#include <vkjr2/kernels/layout.hpp>
#include <vkjr2/kernels/planes.hpp>

#include <string>

namespace vkjr2::kernels {

std::string PlaneLayout::str() const {
  if (plain()) return "plain";
  return std::to_string(hp) + "×" + std::to_string(wp) + " at (" + std::to_string(top) + ", " +
         std::to_string(left) + ")";
}

std::string layout_misfit(const Shape& shape, const PlaneLayout& layout) {
  if (shape.rank() != 4) return "the image " + shape.str() + " is not [N, C, H, W]";
  if (layout.plain()) return {};
  if (layout.top < 0 || layout.left < 0 || std::int64_t(layout.hp) < layout.top + shape[2] ||
      std::int64_t(layout.wp) < layout.left + shape[3]) {
    return "planes " + layout.str() + " do not hold " + shape.str();
  }
  return {};
}

PlaneLayout Planes::geometry() const noexcept {
  if (padded() || shape.rank() != 4) return layout;
  return PlaneLayout{std::uint32_t(shape[2]), std::uint32_t(shape[3]), 0, 0};
}

Planes Planes::of(const Tensor& x) {
  Planes p;
  p.data = x;
  p.shape = x.shape();
  return p;
}

Planes Planes::make(Stream& stream, const Shape& shape, const PlaneLayout& layout) {
  if (shape.rank() != 4 || layout.top < 0 || layout.left < 0 ||
      (!layout.plain() && (layout.hp == 0 || layout.wp == 0))) {
    throw InvalidArgument("Planes::make", "planes " + layout.str() + " for an image " + shape.str(),
                          "pass a 4-D shape and take the layout from the consumer's plan");
  }
  Planes p;
  p.shape = shape;
  p.layout = layout;
  if (layout.plain()) {
    p.data = Tensor::empty(stream.device(), shape);
    return p;
  }
  p.data = Tensor::empty(stream.device(), Shape{shape[0] * shape[1] * std::int64_t(layout.hp) *
                                                std::int64_t(layout.wp)});
  stream.fill(p.data, 0.f);
  return p;
}

Tensor unpad(Stream& stream, const Planes& x) {
  if (!x.padded()) return x.data;
  const std::string why = layout_misfit(x.shape, x.layout);
  if (!why.empty()) {
    throw InvalidArgument("unpad", why + ": the planes leave part of the image out",
                          "have the producer write the image plain");
  }
  const Shape& s = x.shape;
  Tensor y = Tensor::empty(stream.device(), s);
  const Tensor whole = x.data.reshape(Shape{s[0], s[1], x.layout.hp, x.layout.wp});
  slice(stream, whole, SliceStart{0, x.layout.top, x.layout.left}, y);
  return y;
}

}  // namespace vkjr2::kernels
