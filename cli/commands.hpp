// Subcommands of the vkjr2 command runner; one add_* per command file.
#pragma once

#include <CLI/CLI.hpp>

namespace vkjr2::cli {

void add_devices(CLI::App& app);  // devices.cpp
void add_faces(CLI::App& app);    // faces.cpp: detect, embed, verify, identify

}  // namespace vkjr2::cli
