// Host ↔ device image conversion (runtime/image.hpp): layouts, the 0..255 ↔
// 0..1 range, grey ↔ RGB, round trips through the device, and bad shapes.
#include <vkjr2/runtime/error.hpp>
#include <vkjr2/runtime/image.hpp>

#include <gtest/gtest.h>

#include "support/test_device.hpp"

namespace vkjr2 {
namespace {

HostTensor rgb_2x3() {
  HostTensor img;
  img.shape = {2, 3, 3};
  for (int i = 0; i < 18; ++i) img.values.push_back(float(10 * i));
  return img;
}

TEST(Image, PlanesAreChannelMajor) {
  const HostTensor img = rgb_2x3();
  const std::vector<float> p = image_to_planes(img);
  ASSERT_EQ(p.size(), 18u);
  // Pixel (y, x) channel k is values[(y·3 + x)·3 + k] and planes[k·6 + y·3 + x].
  for (int y = 0; y < 2; ++y) {
    for (int x = 0; x < 3; ++x) {
      for (int k = 0; k < 3; ++k) {
        EXPECT_EQ(p[std::size_t(k * 6 + y * 3 + x)], img.values[std::size_t((y * 3 + x) * 3 + k)]);
      }
    }
  }
  const std::vector<float> unit = image_to_planes(img, 3, 255.f);
  EXPECT_FLOAT_EQ(unit[1], img.values[3] / 255.f);
  const std::vector<float> grey = image_to_planes(img, 1, 255.f);
  ASSERT_EQ(grey.size(), 6u);
  EXPECT_FLOAT_EQ(grey[0], (0 + 10 + 20) / (3 * 255.f));
  const HostTensor back = planes_to_image(unit, 3, 2, 3, 3, 255.f);
  for (std::size_t i = 0; i < back.values.size(); ++i) {
    EXPECT_NEAR(back.values[i], std::min(img.values[i], 255.f), 1e-4);
  }
  const HostTensor from_grey = planes_to_image(grey, 1, 2, 3, 3, 255.f);
  EXPECT_EQ(from_grey.values[0], from_grey.values[1]);
  EXPECT_EQ(from_grey.shape, (std::vector<std::int64_t>{2, 3, 3}));
}

TEST(Image, RoundTripThroughTheDevice) {
  HostTensor img = rgb_2x3();
  img.shape = {1, 2, 3, 3};  // a batch of one is accepted
  const Tensor t = image_to_device(test::device(), img);
  EXPECT_EQ(t.shape(), (Shape{1, 3, 2, 3}));
  const HostTensor back = image_to_host(t);
  EXPECT_EQ(back.shape, (std::vector<std::int64_t>{2, 3, 3}));
  EXPECT_EQ(back.values, img.values);
}

TEST(Image, BadShapesNameTheFix) {
  HostTensor flat;
  flat.shape = {6};
  flat.values.assign(6, 0.f);
  EXPECT_THROW(image_to_planes(flat), InvalidArgument);
  HostTensor two;
  two.shape = {2, 2, 2};
  two.values.assign(8, 0.f);
  EXPECT_THROW(image_to_planes(two, 1), InvalidArgument);  // grey only from RGB
  const std::vector<float> planes(5, 0.f);
  EXPECT_THROW(planes_to_image(planes, 1, 2, 3), InvalidArgument);
  EXPECT_THROW(image_to_host(Tensor::from(test::device(), Shape{6}, std::vector<float>(6, 0.f))),
               InvalidArgument);
}

}  // namespace
}  // namespace vkjr2
