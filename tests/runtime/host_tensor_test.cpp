#include <vkjr2/runtime/host_tensor.hpp>

#include <gtest/gtest.h>
#include <unistd.h>

#include <filesystem>

#include "support/test_device.hpp"

namespace vkjr2 {
namespace {

namespace fs = std::filesystem;

TEST(HostTensor, NumelAndShapeChecks) {
  EXPECT_EQ((HostTensor{{}, {1.f}}).numel(), 1);
  EXPECT_EQ((HostTensor{{2, 0, 3}, {}}).numel(), 0);
  EXPECT_EQ((HostTensor{{2, 3, 4}, {}}).numel(), 24);
  EXPECT_EQ(shape_str(std::vector<std::int64_t>{2, 3}), "[2, 3]");
  EXPECT_EQ(shape_str({}), "[]");
  EXPECT_THROW((HostTensor{{2, -1}, {}}).numel(), InvalidArgument);
  const std::vector<std::int64_t> huge = {1ll << 32, 1ll << 32};
  EXPECT_THROW(checked_numel(huge, "huge"), InvalidArgument);
  EXPECT_EQ(checked_numel(std::vector<std::int64_t>{4, 4}, "x", 16), 16);
  EXPECT_THROW(checked_numel(std::vector<std::int64_t>{4, 5}, "x", 16), InvalidArgument);
}

TEST(HostTensor, AtomicWriteReplacesOrLeavesUntouched) {
  const fs::path dir = fs::temp_directory_path() / ("vkjr2_ht_" + std::to_string(::getpid()));
  fs::remove_all(dir);
  fs::create_directories(dir);
  const fs::path path = dir / "f.bin";
  const std::vector<std::byte> a(5, std::byte{1}), b(3, std::byte{2});
  write_file_atomic(path, a, "test");
  EXPECT_EQ(read_file_bytes(path, "test"), a);
  write_file_atomic(path, b, "test");
  EXPECT_EQ(read_file_bytes(path, "test"), b);
  try {
    write_file_atomic(dir / "missing_dir" / "g.bin", a, "test");
    ADD_FAILURE() << "no error";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("g.bin"), std::string::npos) << e.what();
  }
  std::size_t files = 0;
  for ([[maybe_unused]] const auto& e : fs::directory_iterator(dir)) ++files;
  EXPECT_EQ(files, 1u);
  EXPECT_THROW(read_file_bytes(dir / "nope", "test"), Error);
  fs::remove_all(dir);
}

TEST(HostTensor, UploadsToDevice) {
  const HostTensor t{{2, 3}, {1, 2, 3, 4, 5, 6}};
  const Tensor d = to_device(test::device(), t, "t");
  EXPECT_EQ(d.shape(), Shape({2, 3}));
  EXPECT_EQ(d.download(), t.values);
  const Tensor s = to_device(test::device(), HostTensor{{}, {7.f}});
  EXPECT_EQ(s.download(), std::vector<float>{7.f});
  try {
    to_device(test::device(), HostTensor{{1, 1, 1, 1, 2}, {1, 2}}, "w5");
    ADD_FAILURE() << "no error";
  } catch (const InvalidArgument& e) {
    EXPECT_NE(std::string(e.what()).find("'w5' has rank 5"), std::string::npos) << e.what();
  }
  EXPECT_THROW(to_device(test::device(), HostTensor{{3}, {1.f}}), InvalidArgument);
}

}  // namespace
}  // namespace vkjr2
