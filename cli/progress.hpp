// A one-line progress bar with rate and ETA on stderr, drawn only when
// stderr is a terminal and not silenced (--quiet); a no-op otherwise.
#pragma once

#include <chrono>
#include <cstddef>
#include <string>

namespace vkjr2::cli {

class Progress {
 public:
  // total = 0 when unknown (no bar, no ETA).
  Progress(std::string label, std::size_t total, bool quiet);
  ~Progress();
  Progress(const Progress&) = delete;
  Progress& operator=(const Progress&) = delete;
  void update(std::size_t done);
  void done();  // clears the line

 private:
  std::string label_;
  std::size_t total_;
  bool enabled_;
  bool drawn_ = false;
  std::chrono::steady_clock::time_point start_, last_;
};

}  // namespace vkjr2::cli
