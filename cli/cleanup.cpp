#include "cleanup.hpp"

#include <vkjr2/runtime/error.hpp>

#include <fcntl.h>
#include <pthread.h>
#include <unistd.h>

#include <csignal>
#include <cstdio>
#include <cstring>
#include <mutex>
#include <string>
#include <system_error>
#include <thread>
#include <vector>

namespace vkjr2::cli {
namespace fs = std::filesystem;

namespace {

struct Registry {
  std::mutex mutex;
  std::vector<fs::path> watched;  // folders to scan for our temporary files
  std::vector<fs::path> created;  // folders this process made, in creation order
};

Registry& registry() {
  static Registry r;
  return r;
}

// Our temporary names: media.cpp's "NAME.tmp-PID.EXT" and write_file_atomic's
// ".NAME.tmp.PID.N".
bool is_our_temporary(const std::string& name, const std::string& pid) {
  return name.find(".tmp-" + pid + ".") != std::string::npos ||
         name.find(".tmp." + pid + ".") != std::string::npos;
}

int clean_up() {
  Registry& r = registry();
  const std::lock_guard lock(r.mutex);
  const std::string pid = std::to_string(::getpid());
  int removed = 0;
  for (const fs::path& dir : r.watched) {
    std::error_code ec;
    std::vector<fs::path> doomed;
    for (const auto& e : fs::directory_iterator(dir, ec)) {
      if (is_our_temporary(e.path().filename().string(), pid)) doomed.push_back(e.path());
    }
    for (const fs::path& p : doomed) removed += fs::remove(p, ec) ? 1 : 0;
  }
  // Deepest first; fs::remove leaves a folder that is not empty alone.
  for (auto it = r.created.rbegin(); it != r.created.rend(); ++it) {
    std::error_code ec;
    if (fs::is_empty(*it, ec) && !ec) fs::remove(*it, ec);
  }
  return removed;
}

// The stderr the command started with, duplicated when the signals are
// installed: the interruption message goes there even while QuietDecoders
// (cli/media.hpp) points descriptor 2 at /dev/null around a decoder call.
int report_fd = -1;

void wait_for_signals(sigset_t set) {
  int sig = 0;
  while (sigwait(&set, &sig) != 0) {
  }
  const int removed = clean_up();
  const char* name = sig == SIGINT ? "SIGINT" : sig == SIGTERM ? "SIGTERM" : "SIGHUP";
  char line[160];
  const int n = std::snprintf(line, sizeof line,
                              "\nvkjr2: error: interrupted by %s; removed %d temporary file%s\n",
                              name, removed, removed == 1 ? "" : "s");
  if (n > 0) {
    // Best effort: nothing else to do if stderr is gone.
    [[maybe_unused]] const ssize_t w =
        ::write(report_fd >= 0 ? report_fd : STDERR_FILENO, line, std::size_t(n));
  }
  ::_exit(128 + sig);
}

}  // namespace

void install_signal_cleanup() {
  sigset_t set;
  sigemptyset(&set);
  sigaddset(&set, SIGINT);
  sigaddset(&set, SIGTERM);
  sigaddset(&set, SIGHUP);
  // Threads made later (the Vulkan driver's) inherit the mask, so only the
  // waiting thread receives these signals.
  if (pthread_sigmask(SIG_BLOCK, &set, nullptr) != 0) return;
  report_fd = ::fcntl(STDERR_FILENO, F_DUPFD_CLOEXEC, 3);  // set before the thread starts
  std::thread(wait_for_signals, set).detach();
}

void watch_output_folder(const fs::path& dir) {
  Registry& r = registry();
  const std::lock_guard lock(r.mutex);
  const fs::path d = dir.empty() ? fs::path(".") : dir;
  for (const fs::path& w : r.watched)
    if (w == d) return;
  r.watched.push_back(d);
}

void create_output_folder(const fs::path& dir, const char* what) {
  // The missing folders from the outermost in.
  std::vector<fs::path> missing;
  std::error_code ec;
  for (fs::path p = dir.lexically_normal(); !p.empty() && !fs::exists(p, ec); p = p.parent_path()) {
    if (p.has_filename()) missing.insert(missing.begin(), p);
    if (p == p.parent_path()) break;
  }
  for (const fs::path& p : missing) {
    if (!fs::create_directory(p, ec) && ec) {
      throw Error(what, "cannot create the folder " + p.string() + ": " + ec.message(),
                  "pass a folder you can write to");
    }
    Registry& r = registry();
    const std::lock_guard lock(r.mutex);
    r.created.push_back(p);
  }
  watch_output_folder(dir);
}

void cleanup_after_failure() { clean_up(); }

}  // namespace vkjr2::cli
