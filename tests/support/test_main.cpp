// GoogleTest main for vkjr2: validation messages fail the test that caused
// them (see test_device.cpp); messages outside tests fail the process.
#include <gtest/gtest.h>

#include <cstdio>

#include "support/test_device.hpp"

int main(int argc, char** argv) {
  ::testing::InitGoogleTest(&argc, argv);
  const int result = RUN_ALL_TESTS();
  const std::size_t outside = vkjr2::test::shutdown();
  if (outside > 0) {
    std::fprintf(stderr, "%zu Vulkan validation message(s) outside tests\n", outside);
    return 1;
  }
  return result;
}
