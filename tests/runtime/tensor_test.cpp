#include <vkjr2/runtime/tensor.hpp>

#include <gtest/gtest.h>

#include "support/test_device.hpp"

namespace vkjr2 {
namespace {

TEST(Shape, BasicsAndErrors) {
  Shape s{2, 3, 4, 5};
  EXPECT_EQ(s.rank(), 4);
  EXPECT_EQ(s.numel(), 120);
  EXPECT_EQ(s[-1], 5);
  EXPECT_EQ(s.str(), "[2, 3, 4, 5]");
  EXPECT_EQ(Shape{}.numel(), 1);  // a scalar
  EXPECT_THROW((Shape{1, 2, 3, 4, 5}), InvalidArgument);
  EXPECT_THROW((Shape{2, -1}), InvalidArgument);
  EXPECT_THROW(s[4], InvalidArgument);
}

void roundtrip(const Device& dev) {
  for (std::int64_t n : {1, 3, 1000, 123457}) {
    SCOPED_TRACE("n=" + std::to_string(n));
    const auto values = test::random_floats(std::size_t(n), std::uint32_t(n));
    Tensor t = Tensor::from(dev, {n}, values);
    EXPECT_EQ(t.download(), values);
  }
}

TEST(Tensor, RoundTripMapped) {
  Device& dev = test::device();
  ASSERT_FALSE(dev.staging());
  Tensor t = Tensor::empty(dev, {4});
  EXPECT_NE(t.mapped(), nullptr);
  roundtrip(dev);
}

TEST(Tensor, RoundTripThroughStaging) {
  DeviceOptions o = test::options();
  o.force_staging = true;
  Device dev(o);
  ASSERT_TRUE(dev.staging());
  Tensor t = Tensor::empty(dev, {4});
  EXPECT_EQ(t.mapped(), nullptr);
  roundtrip(dev);
  // Larger than one staging chunk (32 MiB).
  const auto values = test::random_floats(9'000'000, 5);
  EXPECT_EQ(Tensor::from(dev, {9'000'000}, values).download(), values);
}

TEST(Tensor, ViewsAndReshape) {
  Device& dev = test::device();
  std::vector<float> v(24);
  for (int i = 0; i < 24; ++i) v[i] = float(i);
  Tensor t = Tensor::from(dev, {2, 3, 4}, v);
  Tensor second = t.view({3, 4}, 12);
  EXPECT_EQ(second.download()[0], 12.f);
  EXPECT_EQ(t.reshape({6, 4}).shape(), (Shape{6, 4}));
  EXPECT_THROW(t.reshape({5, 5}), InvalidArgument);
  EXPECT_THROW(t.view({3, 4}, 13), InvalidArgument);
  EXPECT_THROW(t.view({3, 4}, -1), InvalidArgument);
}

TEST(Tensor, HostSizeAndTypeMismatchesAreClearErrors) {
  Device& dev = test::device();
  Tensor t = Tensor::empty(dev, {10});
  try {
    t.upload(std::vector<float>(9));
    FAIL();
  } catch (const InvalidArgument& e) {
    EXPECT_NE(std::string(e.what()).find("36 bytes"), std::string::npos) << e.what();
  }
  Tensor i = Tensor::empty(dev, {10}, DType::i32);
  EXPECT_THROW(i.upload(std::vector<float>(10)), InvalidArgument);
  EXPECT_THROW(Tensor().download(), InvalidArgument);
  Tensor empty = Tensor::empty(dev, {0, 3});
  EXPECT_EQ(empty.bytes(), 0u);
  EXPECT_TRUE(empty.download().empty());
}

}  // namespace
}  // namespace vkjr2
