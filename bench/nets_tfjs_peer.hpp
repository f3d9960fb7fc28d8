// nets_bench's TF.js peer: face-api itself, on TF.js WASM in a node process.
#pragma once

#include <nlohmann/json.hpp>
#include <sys/types.h>

#include <cstdio>
#include <string>
#include <vector>

namespace vkjr2::bench {

// face-api on TF.js in a node process (faceapi_bench.mjs --serve) that times
// one run per request, so that its runs interleave with ours and both see
// the same load on this shared machine (its speed drifts up to 2× within
// minutes). Unavailable (reason() says why) when node, the script or its
// packages are missing, or the process dies.
class TfjsServer {
 public:
  // script: faceapi_bench.mjs; enabled false: skipped (--no-tfjs);
  // extra_args: more arguments for the script (e.g. --frames DIR).
  TfjsServer(bool enabled, const std::string& script,
             const std::vector<std::string>& extra_args = {});
  ~TfjsServer() { stop(); }
  TfjsServer(const TfjsServer&) = delete;
  TfjsServer& operator=(const TfjsServer&) = delete;

  bool available() const { return !peer_.empty(); }
  const std::string& reason() const { return reason_; }
  const std::string& peer() const { return peer_; }  // "face-api 1.7.15 / TF.js 4.22.0 wasm …"
  const nlohmann::json& about() const { return about_; }  // backend, SIMD, threads, node, machine

  // Seconds of one run of the script's benchmark `name`, as node timed it
  // (the pipe's round trip is not counted).
  double run(const std::string& name);

 private:
  // The next JSON reply holding `key`; other lines (node's own messages)
  // are echoed. Throws (std::runtime_error) with the last line seen when
  // the process ends, or with its error reply.
  nlohmann::json read_reply(const char* key);

  void stop();

  pid_t pid_ = -1;
  FILE* to_ = nullptr;
  FILE* from_ = nullptr;
  std::string reason_, peer_;
  nlohmann::json about_;
};

}  // namespace vkjr2::bench
