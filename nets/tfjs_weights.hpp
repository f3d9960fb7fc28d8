// TF.js layers/graph-model weights: a `*-weights_manifest.json` (a JSON array
// of groups {"paths": [shard files relative to the manifest], "weights":
// [{"name", "shape", "dtype": "float32"|"int32", "quantization"?: {"dtype":
// "uint8"|"uint16"|"float16", "scale", "min"}}]}) plus binary shards. A group's
// shards concatenate in order; its tensors follow in manifest order without
// padding; uint8/uint16 values dequantize as q*scale + min, float16 ones are
// IEEE halves; row-major (conv filters HWIO). This is how the face-api models
// ship.
#pragma once

#include <vkjr2/runtime/host_tensor.hpp>

#include <cstddef>
#include <filesystem>
#include <span>
#include <string>
#include <string_view>
#include <unordered_map>
#include <utility>
#include <vector>

namespace vkjr2::nets {

class TfjsWeights {
 public:
  TfjsWeights() = default;
  TfjsWeights(std::vector<std::pair<std::string, HostTensor>> entries, std::string source);

  // Manifest order.
  const std::vector<std::pair<std::string, HostTensor>>& entries() const noexcept {
    return entries_;
  }
  std::size_t size() const noexcept { return entries_.size(); }
  bool contains(std::string_view name) const noexcept;
  // Throws InvalidArgument naming the missing weight, the source file and the
  // closest names present.
  const HostTensor& at(std::string_view name) const;
  // Sum of numel over all weights.
  std::int64_t parameter_count() const;
  // The manifest path (or "<memory>").
  const std::string& source() const noexcept { return source_; }

 private:
  std::vector<std::pair<std::string, HostTensor>> entries_;
  std::unordered_map<std::string, std::size_t> index_;
  std::string source_;
};

// Reads the manifest and its shards (resolved relative to the manifest's
// directory). Errors name the manifest, the group/shard and the weight: a
// missing shard file, a truncated group (bytes expected vs found), extra
// trailing bytes, an unknown dtype or quantization, a malformed manifest.
// int32 weights are converted to float (exact up to 2^24).
TfjsWeights load_tfjs_weights(const std::filesystem::path& manifest_path);

// Same from memory: `group_bytes[g]` is group g's shards already concatenated
// (one entry per manifest group). `source` names the input in errors.
TfjsWeights parse_tfjs_weights(std::string_view manifest_json,
                               std::span<const std::span<const std::byte>> group_bytes,
                               std::string_view source = "<memory>");

}  // namespace vkjr2::nets
