// A PyTorch peer of a benchmark: a script of tools/ run as a child process
// after our measurement (`vkjr2 bench restore`, `vkjr2 bench cotrain`). It
// prints one JSON line with the result; its other lines are echoed.
#pragma once

#include <vkjr2/runtime/error.hpp>

#include <CLI/CLI.hpp>
#include <nlohmann/json.hpp>
#include <sys/wait.h>
#include <unistd.h>

#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <initializer_list>
#include <string>
#include <utility>

#include "cli/checks.hpp"

namespace vkjr2::cli {

inline std::string shell_quote(const std::string& s) {
  std::string q = "'";
  for (char c : s) q += c == '\'' ? std::string("'\\''") : std::string(1, c);
  return q + "'";
}

// The options every PyTorch peer takes: --threads, --no-torch, --python,
// --torch-script (default: `script`).
struct TorchPeerOptions {
  int threads = 2;
  bool enabled = true;
  std::string python = "/usr/bin/python3";
  std::string script;
};

inline void add_torch_peer_options(CLI::App& app, TorchPeerOptions& o) {
  app.add_option("--threads", o.threads, "PyTorch peer's threads (torch.set_num_threads)")
      ->default_val(o.threads)
      ->check(integer_range(1, 1024));
  app.add_flag("!--no-torch", o.enabled, "Skip the PyTorch peer");
  app.add_option("--python", o.python, "The Python that has torch")->default_val(o.python);
  app.add_option("--torch-script", o.script, "The PyTorch peer's script");
}

class TorchPeer {
 public:
  // enabled: false with --no-torch. python must import torch and script exist.
  explicit TorchPeer(const TorchPeerOptions& o) : python_(o.python), script_(o.script) {
    if (!o.enabled) {
      reason = "skipped (--no-torch)";
      return;
    }
    if (::access(python_.c_str(), X_OK) != 0 ||
        std::system((shell_quote(python_) + " -c 'import torch' > /dev/null 2>&1").c_str()) != 0) {
      reason = "not available (install python3-torch)";
      return;
    }
    if (!std::filesystem::exists(script_)) {
      reason = "not available (" + script_ + " not found; pass --torch-script PATH)";
      return;
    }
    available = true;
  }

  // Runs `python script` with `args` (already quoted for the shell; `shown`:
  // how they are printed) and returns the JSON line holding every key of
  // `keys`. Throws Error(op) naming the command when it fails or prints none.
  nlohmann::json run(const char* op, const std::string& args, const std::string& shown,
                     std::initializer_list<const char*> keys) {
    command_line = python_ + " " + script_ + shown;
    std::fprintf(stderr, "%s: %s\n", op, command_line.c_str());
    std::fflush(stdout);  // the child must not inherit unwritten output
    std::fflush(stderr);
    FILE* pipe = ::popen((shell_quote(python_) + " " + shell_quote(script_) + args).c_str(), "r");
    if (pipe == nullptr) throw Error(op, "cannot start " + python_, "check it, or pass --no-torch");
    nlohmann::json result;
    std::string last;
    char* line = nullptr;
    std::size_t cap = 0;
    ssize_t n = 0;
    while ((n = ::getline(&line, &cap, pipe)) > 0) {
      std::string text(line, std::size_t(n));
      while (!text.empty() && (text.back() == '\n' || text.back() == '\r')) text.pop_back();
      nlohmann::json j = nlohmann::json::parse(text, nullptr, /*allow_exceptions=*/false);
      bool is_result = j.is_object();
      for (const char* k : keys) is_result = is_result && j.contains(k);
      if (is_result) {
        result = std::move(j);
      } else if (!text.empty()) {
        std::fprintf(stderr, "  | %s\n", text.c_str());
        last = text;
      }
    }
    std::free(line);
    const int status = ::pclose(pipe);
    if (status != 0 || !result.is_object()) {
      const int code = status >= 0 && WIFEXITED(status) ? WEXITSTATUS(status) : -1;
      throw Error(op,
                  "the PyTorch peer failed (exit code " + std::to_string(code) +
                      (result.is_object() ? "" : ", no JSON result") +
                      (last.empty() ? "" : ": " + last) + ")",
                  "run `" + command_line + "` alone to see why, or pass --no-torch");
    }
    return result;
  }

  bool available = false;
  std::string reason;        // why not, when not available
  std::string command_line;  // the last run, as printed

 private:
  std::string python_, script_;
};

}  // namespace vkjr2::cli
