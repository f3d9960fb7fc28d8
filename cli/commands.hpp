// Subcommands of the vkjr2 command runner; one add_* per command file.
#pragma once

#include <CLI/CLI.hpp>

namespace vkjr2::cli {

void add_devices(CLI::App& app);       // devices.cpp
void add_faces(CLI::App& app);         // faces.cpp: detect, embed, verify, identify
void add_simulate(CLI::App& app);      // simulate.cpp
void add_sim_train(CLI::App& app);     // sim_train.cpp
void add_wave(CLI::App& app);          // wave.cpp
void add_bench(CLI::App& app);         // bench.cpp: bench sim, bench kernels
void add_sim_validate(CLI::App& app);  // sim_validate.cpp
void add_demo(CLI::App& app);          // demo.cpp: the turbulence-vs-recognition study

}  // namespace vkjr2::cli
