// Subcommands of the vkjr2 command runner; one add_* per command file.
#pragma once

#include <CLI/CLI.hpp>

#include <string_view>

namespace vkjr2::cli {

void add_devices(CLI::App& app);          // devices.cpp
void add_faces(CLI::App& app);            // faces.cpp: detect, embed, verify, identify
void add_simulate(CLI::App& app);         // simulate.cpp
void add_sim_train(CLI::App& app);        // sim_train.cpp
void add_restore_train(CLI::App& app);    // restore_train.cpp
void add_restore(CLI::App& app);          // restore.cpp
void add_restore_study(CLI::App& app);    // restore_study.cpp: wave-clips, restore-score
void add_wave(CLI::App& app);             // wave.cpp
void add_bench(CLI::App& app);            // bench.cpp: runs bench/'s programs
void add_sim_validate(CLI::App& app);     // sim_validate.cpp
void add_dataset(CLI::App& app);          // dataset.cpp: dataset make, dataset merge
void add_demo(CLI::App& app);             // jr2_demo.cpp: the JR² study with the shipped artifacts
void add_demo_turbulence(CLI::App& app);  // demo.cpp: the turbulence-vs-recognition study
void add_eval(CLI::App& app);             // eval.cpp: the JR² evaluation of a benchmark
void add_cotrain(CLI::App& app);          // cotrain.cpp: JR² co-optimization
void add_estimate(CLI::App& app);         // estimate.cpp: estimate, estimate-train
void add_gate(CLI::App& app);             // gate.cpp: gate train

// bench.cpp: `vkjr2 bench NAME ARGS...` runs NAME's program with ARGS (argv,
// argc of them) in place of this process; returns 1 after printing the error
// when it cannot. NAME must be one is_benchmark() accepts.
bool is_benchmark(std::string_view name);
int run_benchmark(std::string_view name, int argc, char** argv);

}  // namespace vkjr2::cli
