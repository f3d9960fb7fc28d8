// Element-wise comparison of a device result with its C++ reference.
#pragma once

#include <gtest/gtest.h>

#include <cmath>
#include <cstddef>
#include <vector>

namespace vkjr2::test {

// Every |got[i] − want[i]| ≤ atol + rtol·|want[i]|; stops at the first miss.
inline void expect_all_near(const std::vector<float>& got, const std::vector<float>& want,
                            double rtol, double atol) {
  ASSERT_EQ(got.size(), want.size());
  for (std::size_t i = 0; i < got.size(); ++i) {
    ASSERT_NEAR(got[i], want[i], atol + rtol * std::fabs(want[i])) << "at " << i;
  }
}

}  // namespace vkjr2::test
