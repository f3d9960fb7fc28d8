// Proves an installed vkjr2 is usable: headers from the prefix, the library
// through the exported vkjr2::vkjr2 target, and a device that comes up.
#include <vkjr2/runtime/device.hpp>
#include <vkjr2/runtime/error.hpp>

#include <cstdio>
#include <exception>

int main() {
  try {
    vkjr2::Device device;
    std::printf("vkjr2 consumer: device %s\n", device.info().name.c_str());
    return 0;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "vkjr2 consumer: %s\n", e.what());
    return 1;
  }
}
