// Nothing left behind: when a command fails or is interrupted, the temporary
// outputs it was writing (OUT.tmp-PID.ext, .OUT.tmp.PID.N) and the folders it
// created (while still empty) are removed.
//
// install_signal_cleanup(), called first thing in main, blocks SIGINT, SIGTERM
// and SIGHUP in every thread and starts one thread that waits for them; on a
// signal that thread prints one line, cleans up and exits with 128 + the
// signal number (130 for SIGINT, 143 for SIGTERM, 129 for SIGHUP).
#pragma once

#include <filesystem>

namespace vkjr2::cli {

void install_signal_cleanup();

// A folder the command writes into: this process's temporary files in it are
// removed on a signal or a failure.
void watch_output_folder(const std::filesystem::path& dir);

// Creates `dir` and its missing parents, remembers each folder it made (removed
// on a signal or a failure while still empty) and watches `dir`. Throws Error
// naming `what` when a folder cannot be made.
void create_output_folder(const std::filesystem::path& dir, const char* what);

// The clean-up a signal does, for a command that failed (main calls it).
void cleanup_after_failure();

}  // namespace vkjr2::cli
