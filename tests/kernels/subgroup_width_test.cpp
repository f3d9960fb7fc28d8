// The kernels that reduce with subgroup operations must not assume a
// subgroup size. ctest's kernels.subgroup16 entry reruns them on a 16-lane
// llvmpipe (LP_NATIVE_VECTOR_WIDTH=512) with VKJR2_EXPECT_SUBGROUP_SIZE=16;
// this test makes sure that run really got 16 lanes.
#include <gtest/gtest.h>

#include <cstdlib>
#include <string>

#include "support/test_device.hpp"

namespace vkjr2 {
namespace {

TEST(SubgroupWidth, DeviceHasTheRequestedSubgroupSize) {
  const char* want = std::getenv("VKJR2_EXPECT_SUBGROUP_SIZE");
  if (want == nullptr) GTEST_SKIP() << "VKJR2_EXPECT_SUBGROUP_SIZE is not set";
  const DeviceInfo& info = test::device().info();
  if (info.name.rfind("llvmpipe", 0) != 0) {
    GTEST_SKIP() << "the subgroup size is set through llvmpipe only; device is " << info.name;
  }
  EXPECT_EQ(std::to_string(info.subgroup_size), std::string(want))
      << info.name << ": LP_NATIVE_VECTOR_WIDTH did not take effect";
}

}  // namespace
}  // namespace vkjr2
