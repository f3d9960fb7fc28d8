#include "nets_tfjs_peer.hpp"

#include <vkjr2/runtime/error.hpp>

#include <sys/wait.h>
#include <unistd.h>

#include <csignal>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <stdexcept>
#include <string>

namespace vkjr2::bench {

namespace fs = std::filesystem;

TfjsServer::TfjsServer(bool enabled, const std::string& script,
                       const std::vector<std::string>& extra_args) {
  if (!enabled) {
    reason_ = "skipped (--no-tfjs)";
    return;
  }
  if (std::system("command -v node > /dev/null 2>&1") != 0) {
    reason_ = "node is not installed (apt-get install nodejs, then scripts/setup)";
    return;
  }
  if (!fs::exists(script)) {
    reason_ = script + " not found (pass --faceapi-script PATH)";
    return;
  }
  std::signal(SIGPIPE, SIG_IGN);  // a dead server is an error below, not a signal
  int to_child[2], from_child[2];
  if (::pipe(to_child) != 0) {
    reason_ = "cannot make pipes to node";
    return;
  }
  if (::pipe(from_child) != 0) {
    ::close(to_child[0]);
    ::close(to_child[1]);
    reason_ = "cannot make pipes to node";
    return;
  }
  // No warm-ups at start: time_interleaved warms every peer up, this one too.
  std::vector<std::string> args = {"node", script, "--serve", "--warmup", "0"};
  args.insert(args.end(), extra_args.begin(), extra_args.end());
  std::string command;
  for (const std::string& a : args) command += (command.empty() ? "" : " ") + a;
  std::fprintf(stderr, "bench: %s\n", command.c_str());
  std::vector<char*> argv;
  for (std::string& a : args) argv.push_back(a.data());
  argv.push_back(nullptr);
  std::fflush(stdout);  // the child must not inherit unwritten output
  std::fflush(stderr);
  pid_ = ::fork();
  if (pid_ == 0) {
    ::dup2(to_child[0], 0);
    ::dup2(from_child[1], 1);
    ::dup2(from_child[1], 2);  // its errors come back as lines too
    ::close(to_child[1]);
    ::close(from_child[0]);
    ::execvp("node", argv.data());
    ::_exit(127);
  }
  ::close(to_child[0]);
  ::close(from_child[1]);
  if (pid_ < 0) {
    ::close(to_child[1]);
    ::close(from_child[0]);
    reason_ = "cannot start node";
    return;
  }
  to_ = ::fdopen(to_child[1], "w");
  from_ = ::fdopen(from_child[0], "r");
  try {
    const nlohmann::json ready = read_reply("ready");
    about_ = ready;
    about_.erase("ready");
    peer_ = ready.at("peer").get<std::string>();
  } catch (const std::exception& e) {
    reason_ = std::string(e.what()) + " (scripts/setup installs node and face-api's packages)";
    stop();
  }
}

double TfjsServer::run(const std::string& name) {
  if (!available()) throw InvalidArgument("nets_bench", "the TF.js peer is unavailable");
  if (std::fprintf(to_, "%s\n", name.c_str()) < 0 || std::fflush(to_) != 0) {
    throw InvalidArgument("nets_bench", "the TF.js peer (node) stopped reading requests");
  }
  try {
    return read_reply("name").at("ms").get<double>() * 1e-3;
  } catch (const std::exception& e) {
    throw InvalidArgument("nets_bench", "the TF.js peer failed timing " + name + ": " + e.what(),
                          "run node bench/faceapi_bench.mjs alone to see why, or pass --no-tfjs");
  }
}

nlohmann::json TfjsServer::read_reply(const char* key) {
  std::string last;
  char* line = nullptr;
  std::size_t cap = 0;
  ssize_t n = 0;
  while ((n = ::getline(&line, &cap, from_)) > 0) {
    std::string text(line, std::size_t(n));
    while (!text.empty() && (text.back() == '\n' || text.back() == '\r')) text.pop_back();
    nlohmann::json j = nlohmann::json::parse(text, nullptr, /*allow_exceptions=*/false);
    if (j.is_object() && j.contains(key)) {
      std::free(line);
      return j;
    }
    if (j.is_object() && j.contains("error")) {
      std::free(line);
      throw std::runtime_error("faceapi_bench.mjs: " + j.at("error").get<std::string>());
    }
    std::fprintf(stderr, "  | %s\n", text.c_str());
    if (!text.empty()) last = text;
  }
  std::free(line);
  throw std::runtime_error("faceapi_bench.mjs ended" + (last.empty() ? "" : ": " + last));
}

void TfjsServer::stop() {
  if (to_ != nullptr) {
    std::fputs("quit\n", to_);
    std::fclose(to_);
    to_ = nullptr;
  }
  if (from_ != nullptr) {
    std::fclose(from_);
    from_ = nullptr;
  }
  if (pid_ > 0) {
    ::waitpid(pid_, nullptr, 0);
    pid_ = -1;
  }
}

}  // namespace vkjr2::bench
