// Bad input must be a clear error: an InvalidArgument whose message names
// what is wrong.
#pragma once

#include <vkjr2/runtime/error.hpp>

#include <gtest/gtest.h>

#include <string>
#include <string_view>

namespace vkjr2::test {

// Runs f; fails unless it throws InvalidArgument with `needle` in its message.
template <class F>
void expect_invalid_argument(F&& f, std::string_view needle) {
  try {
    f();
    ADD_FAILURE() << "no exception; expected one mentioning '" << needle << "'";
  } catch (const InvalidArgument& e) {
    EXPECT_NE(std::string(e.what()).find(needle), std::string::npos) << e.what();
  }
}

}  // namespace vkjr2::test
