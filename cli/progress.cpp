#include "progress.hpp"

#include <unistd.h>

#include <algorithm>
#include <cstdio>

namespace vkjr2::cli {

Progress::Progress(std::string label, std::size_t total, bool quiet)
    : label_(std::move(label)),
      total_(total),
      enabled_(!quiet && ::isatty(STDERR_FILENO) == 1),
      start_(std::chrono::steady_clock::now()),
      last_(start_) {}

Progress::~Progress() { done(); }

void Progress::update(std::size_t done_count) {
  if (!enabled_) return;
  const auto now = std::chrono::steady_clock::now();
  if (drawn_ && now - last_ < std::chrono::milliseconds(100) && done_count != total_) return;
  last_ = now;
  const double seconds = std::chrono::duration<double>(now - start_).count();
  const double rate = seconds > 0 ? double(done_count) / seconds : 0.0;
  std::string line = label_ + " " + std::to_string(done_count);
  if (total_ > 0) {
    constexpr int kWidth = 24;
    const double f = std::min(1.0, double(done_count) / double(total_));
    const int filled = static_cast<int>(f * kWidth);
    line += "/" + std::to_string(total_) + " [" + std::string(std::size_t(filled), '=') +
            std::string(std::size_t(kWidth - filled), ' ') + "]";
  }
  char buf[96];
  std::snprintf(buf, sizeof buf, " %.2f/s", rate);
  line += buf;
  if (total_ > 0 && rate > 0 && done_count < total_) {
    const auto eta = static_cast<long>(double(total_ - done_count) / rate);
    std::snprintf(buf, sizeof buf, " ETA %ld:%02ld", eta / 60, eta % 60);
    line += buf;
  }
  std::fprintf(stderr, "\r%s\033[K", line.c_str());
  std::fflush(stderr);
  drawn_ = true;
}

void Progress::done() {
  if (enabled_ && drawn_) {
    std::fprintf(stderr, "\r\033[K");
    std::fflush(stderr);
    drawn_ = false;
  }
}

}  // namespace vkjr2::cli
