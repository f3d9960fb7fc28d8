#include <vkjr2/nets/tfjs_weights.hpp>

#include <nlohmann/json.hpp>

#include <algorithm>
#include <bit>
#include <cmath>
#include <cstring>
#include <fstream>
#include <iterator>
#include <optional>
#include <unordered_set>

#include "internal/half.hpp"

namespace vkjr2::nets {
namespace {

static_assert(std::endian::native == std::endian::little,
              "TF.js shards are little-endian; add byte swapping for big-endian hosts");

constexpr const char* kOp = "load_tfjs_weights";

enum class Quant : std::uint8_t { none, u8, u16, f16 };

struct WeightSpec {
  std::string name;
  std::vector<std::int64_t> shape;
  std::int64_t numel = 0;
  bool int32 = false;  // dtype "int32" (else "float32")
  Quant quant = Quant::none;
  double scale = 1, min = 0;
  std::uint64_t bytes = 0;
};

struct GroupSpec {
  std::vector<std::string> paths;
  std::vector<WeightSpec> weights;
  std::uint64_t bytes = 0;
};

std::string in_quotes(std::string_view s) { return "'" + std::string(s) + "'"; }

[[noreturn]] void bad_manifest(std::string_view source, const std::string& problem) {
  throw InvalidArgument(kOp, "manifest " + in_quotes(source) + ": " + problem,
                        "the manifest is corrupt or not a TF.js weights manifest; re-fetch the "
                        "model (run scripts/setup)");
}

std::string group_label(std::size_t g, const GroupSpec& spec) {
  std::string s = "group " + std::to_string(g) + " (shards ";
  for (std::size_t i = 0; i < spec.paths.size(); ++i)
    s += (i ? ", " : "") + in_quotes(spec.paths[i]);
  return s + (spec.paths.empty() ? "none)" : ")");
}

WeightSpec parse_weight(const nlohmann::json& w, std::string_view source, std::size_t g,
                        std::size_t i) {
  const std::string where = "group " + std::to_string(g) + " weight " + std::to_string(i);
  if (!w.is_object()) bad_manifest(source, where + " is not an object");
  WeightSpec spec;
  const auto name = w.find("name");
  if (name == w.end() || !name->is_string() || name->get_ref<const std::string&>().empty()) {
    bad_manifest(source, where + " has no \"name\" string");
  }
  spec.name = name->get<std::string>();
  const std::string label = "weight " + in_quotes(spec.name);
  const auto shape = w.find("shape");
  if (shape == w.end() || !shape->is_array()) {
    bad_manifest(source, label + " has no \"shape\" array");
  }
  for (const auto& d : *shape) {
    if (!d.is_number_unsigned() || d.get<std::uint64_t>() > std::uint64_t(INT64_MAX)) {
      bad_manifest(source,
                   label + " has shape entry " + d.dump() + ", expected a non-negative integer");
    }
    spec.shape.push_back(std::int64_t(d.get<std::uint64_t>()));
  }
  // Every element takes <= 4 bytes, so numel * 4 stays below 2^63.
  spec.numel = checked_numel(spec.shape, std::string(source) + " " + label, INT64_MAX / 8);
  const auto dtype = w.find("dtype");
  const std::string dtype_name =
      dtype != w.end() && dtype->is_string() ? dtype->get<std::string>() : std::string();
  if (dtype_name == "int32") {
    spec.int32 = true;
  } else if (dtype_name != "float32") {
    bad_manifest(source, label + " has unknown dtype " +
                             (dtype == w.end() ? std::string("(none)") : dtype->dump()) +
                             " (supported: \"float32\", \"int32\")");
  }
  std::uint64_t elem_bytes = 4;
  if (const auto q = w.find("quantization"); q != w.end() && !q->is_null()) {
    if (!q->is_object())
      bad_manifest(source, label + " has a \"quantization\" that is not an object");
    const auto qd = q->find("dtype");
    const std::string qname =
        qd != q->end() && qd->is_string() ? qd->get<std::string>() : std::string();
    if (qname == "uint8") {
      spec.quant = Quant::u8;
      elem_bytes = 1;
    } else if (qname == "uint16") {
      spec.quant = Quant::u16;
      elem_bytes = 2;
    } else if (qname == "float16") {
      spec.quant = Quant::f16;
      elem_bytes = 2;
      if (spec.int32) {
        bad_manifest(source, label +
                                 " is int32 with float16 quantization, which TF.js does not "
                                 "define");
      }
    } else {
      bad_manifest(source, label + " has unknown quantization dtype " +
                               (qd == q->end() ? std::string("(none)") : qd->dump()) +
                               " (supported: \"uint8\", \"uint16\", \"float16\")");
    }
    if (spec.quant != Quant::f16) {
      const auto scale = q->find("scale");
      const auto min = q->find("min");
      if (scale == q->end() || min == q->end() || !scale->is_number() || !min->is_number() ||
          !std::isfinite(scale->get<double>()) || !std::isfinite(min->get<double>())) {
        bad_manifest(source, label + " has " + qname +
                                 " quantization without finite \"scale\" and \"min\" numbers");
      }
      spec.scale = scale->get<double>();
      spec.min = min->get<double>();
    }
  }
  spec.bytes = std::uint64_t(spec.numel) * elem_bytes;
  return spec;
}

std::vector<GroupSpec> parse_manifest(std::string_view text, std::string_view source) {
  nlohmann::json doc;
  try {
    doc = nlohmann::json::parse(text.begin(), text.end());
  } catch (const nlohmann::json::exception& e) {
    bad_manifest(source, std::string("not valid JSON: ") + e.what());
  }
  // A model.json holds the manifest under "weightsManifest".
  if (doc.is_object() && doc.contains("weightsManifest")) doc = doc["weightsManifest"];
  if (!doc.is_array()) bad_manifest(source, "top level is not a JSON array of weight groups");
  std::vector<GroupSpec> groups;
  std::unordered_set<std::string> names;
  for (std::size_t g = 0; g < doc.size(); ++g) {
    const auto& group = doc[g];
    const std::string where = "group " + std::to_string(g);
    if (!group.is_object()) bad_manifest(source, where + " is not an object");
    GroupSpec spec;
    const auto paths = group.find("paths");
    if (paths == group.end() || !paths->is_array()) {
      bad_manifest(source, where + " has no \"paths\" array");
    }
    for (const auto& p : *paths) {
      if (!p.is_string() || p.get_ref<const std::string&>().empty()) {
        bad_manifest(source, where + " has a shard path " + p.dump() + " that is not a file name");
      }
      spec.paths.push_back(p.get<std::string>());
    }
    const auto weights = group.find("weights");
    if (weights == group.end() || !weights->is_array()) {
      bad_manifest(source, where + " has no \"weights\" array");
    }
    for (std::size_t i = 0; i < weights->size(); ++i) {
      WeightSpec w = parse_weight((*weights)[i], source, g, i);
      if (!names.insert(w.name).second) {
        bad_manifest(source, "weight " + in_quotes(w.name) + " appears twice");
      }
      if (__builtin_add_overflow(spec.bytes, w.bytes, &spec.bytes) ||
          spec.bytes > std::uint64_t(INT64_MAX)) {
        bad_manifest(source, where + " needs more bytes than any file can hold");
      }
      spec.weights.push_back(std::move(w));
    }
    groups.push_back(std::move(spec));
  }
  return groups;
}

void check_group_size(std::string_view source, std::size_t g, const GroupSpec& spec,
                      std::uint64_t found) {
  if (found == spec.bytes) return;
  const std::string label = group_label(g, spec);
  if (found > spec.bytes) {
    throw InvalidArgument(
        kOp,
        "manifest " + in_quotes(source) + ": " + label + " holds " + std::to_string(found) +
            " bytes but its " + std::to_string(spec.weights.size()) + " weights need " +
            std::to_string(spec.bytes) + " (" + std::to_string(found - spec.bytes) +
            " extra trailing bytes: the shapes or quantization in the manifest do not match the "
            "shards)",
        "use the manifest that was written with these shards (re-fetch: run scripts/setup)");
  }
  std::uint64_t offset = 0;
  std::string cut;
  for (const auto& w : spec.weights) {
    if (offset + w.bytes > found) {
      cut = "; weight " + in_quotes(w.name) + " (" + std::to_string(w.bytes) + " bytes at offset " +
            std::to_string(offset) + ") is the first one cut off";
      break;
    }
    offset += w.bytes;
  }
  throw InvalidArgument(
      kOp,
      "manifest " + in_quotes(source) + ": " + label + " holds " + std::to_string(found) +
          " bytes but its " + std::to_string(spec.weights.size()) + " weights need " +
          std::to_string(spec.bytes) + " (truncated: " + std::to_string(spec.bytes - found) +
          " bytes missing" + cut + ")",
      "the shard files are truncated or belong to another model; re-fetch them "
      "(run scripts/setup)");
}

HostTensor decode(const WeightSpec& w, const std::byte* p) {
  HostTensor t;
  t.shape = w.shape;
  t.values.resize(std::size_t(w.numel));
  const std::size_t n = t.values.size();
  auto dequant = [&](double q) {
    const double v = q * w.scale + w.min;  // TF.js computes in double, stores float
    return float(w.int32 ? std::round(v) : v);
  };
  switch (w.quant) {
    case Quant::none:
      if (w.int32) {
        for (std::size_t i = 0; i < n; ++i) {
          std::int32_t v;
          std::memcpy(&v, p + 4 * i, 4);
          t.values[i] = float(v);
        }
      } else if (n) {
        std::memcpy(t.values.data(), p, 4 * n);
      }
      break;
    case Quant::u8:
      for (std::size_t i = 0; i < n; ++i) t.values[i] = dequant(double(std::uint8_t(p[i])));
      break;
    case Quant::u16:
      for (std::size_t i = 0; i < n; ++i) {
        std::uint16_t q;
        std::memcpy(&q, p + 2 * i, 2);
        t.values[i] = dequant(double(q));
      }
      break;
    case Quant::f16:
      for (std::size_t i = 0; i < n; ++i) {
        std::uint16_t h;
        std::memcpy(&h, p + 2 * i, 2);
        t.values[i] = detail::half_to_float(h);
      }
      break;
  }
  return t;
}

TfjsWeights decode_all(const std::vector<GroupSpec>& groups,
                       std::span<const std::span<const std::byte>> group_bytes,
                       std::string_view source) {
  std::vector<std::pair<std::string, HostTensor>> entries;
  for (std::size_t g = 0; g < groups.size(); ++g) {
    const std::byte* p = group_bytes[g].data();
    for (const auto& w : groups[g].weights) {
      entries.emplace_back(w.name, decode(w, p));
      p += w.bytes;
    }
  }
  return TfjsWeights(std::move(entries), std::string(source));
}

std::size_t edit_distance(std::string_view a, std::string_view b) {
  std::vector<std::size_t> row(b.size() + 1);
  for (std::size_t j = 0; j <= b.size(); ++j) row[j] = j;
  for (std::size_t i = 1; i <= a.size(); ++i) {
    std::size_t diag = row[0];
    row[0] = i;
    for (std::size_t j = 1; j <= b.size(); ++j) {
      const std::size_t up = row[j];
      row[j] = std::min({row[j] + 1, row[j - 1] + 1, diag + (a[i - 1] != b[j - 1] ? 1u : 0u)});
      diag = up;
    }
  }
  return row[b.size()];
}

}  // namespace

TfjsWeights::TfjsWeights(std::vector<std::pair<std::string, HostTensor>> entries,
                         std::string source)
    : entries_(std::move(entries)), source_(std::move(source)) {
  for (std::size_t i = 0; i < entries_.size(); ++i) {
    if (!index_.emplace(entries_[i].first, i).second) {
      throw InvalidArgument(
          "TfjsWeights",
          "weight " + in_quotes(entries_[i].first) + " appears twice in " + in_quotes(source_),
          "give every weight a unique name");
    }
  }
}

bool TfjsWeights::contains(std::string_view name) const noexcept {
  return index_.find(std::string(name)) != index_.end();
}

const HostTensor& TfjsWeights::at(std::string_view name) const {
  if (const auto it = index_.find(std::string(name)); it != index_.end()) {
    return entries_[it->second].second;
  }
  std::vector<std::pair<std::size_t, const std::string*>> ranked;
  ranked.reserve(entries_.size());
  for (const auto& e : entries_) ranked.emplace_back(edit_distance(name, e.first), &e.first);
  const std::size_t keep = std::min<std::size_t>(5, ranked.size());
  std::partial_sort(ranked.begin(), ranked.begin() + std::ptrdiff_t(keep), ranked.end());
  std::string near;
  for (std::size_t i = 0; i < keep; ++i) near += (i ? ", " : "") + in_quotes(*ranked[i].second);
  throw InvalidArgument("TfjsWeights::at",
                        "no weight named " + in_quotes(name) + " in " + in_quotes(source_) + " (" +
                            std::to_string(entries_.size()) +
                            " weights); nearest: " + (near.empty() ? std::string("none") : near),
                        "check the weight name against the manifest, or the model file");
}

std::int64_t TfjsWeights::parameter_count() const {
  std::int64_t n = 0;
  for (const auto& e : entries_) n += std::int64_t(e.second.values.size());
  return n;
}

TfjsWeights parse_tfjs_weights(std::string_view manifest_json,
                               std::span<const std::span<const std::byte>> group_bytes,
                               std::string_view source) {
  const std::vector<GroupSpec> groups = parse_manifest(manifest_json, source);
  if (group_bytes.size() != groups.size()) {
    throw InvalidArgument(kOp,
                          "manifest " + in_quotes(source) + " has " +
                              std::to_string(groups.size()) + " weight groups but " +
                              std::to_string(group_bytes.size()) + " byte blocks were given",
                          "pass one concatenated byte block per manifest group");
  }
  // Sizes first, so that nothing is allocated for data the input does not hold.
  for (std::size_t g = 0; g < groups.size(); ++g) {
    check_group_size(source, g, groups[g], group_bytes[g].size());
  }
  return decode_all(groups, group_bytes, source);
}

TfjsWeights load_tfjs_weights(const std::filesystem::path& manifest_path) {
  const std::string source = manifest_path.string();
  const std::vector<std::byte> text = read_file_bytes(manifest_path, kOp);
  const std::vector<GroupSpec> groups = parse_manifest(
      std::string_view(reinterpret_cast<const char*>(text.data()), text.size()), source);
  const std::filesystem::path dir = manifest_path.parent_path();
  std::vector<std::vector<std::byte>> blobs(groups.size());
  for (std::size_t g = 0; g < groups.size(); ++g) {
    // Check sizes before reading, so a wrong manifest fails fast.
    std::uint64_t found = 0;
    for (const auto& p : groups[g].paths) {
      const std::filesystem::path shard = dir / p;
      std::error_code ec;
      const auto size = std::filesystem::file_size(shard, ec);
      if (ec || !std::filesystem::is_regular_file(shard, ec)) {
        throw Error(kOp,
                    "shard " + in_quotes(p) + " of " + group_label(g, groups[g]) + " in manifest " +
                        in_quotes(source) + " is missing (looked for " + in_quotes(shard.string()) +
                        ")",
                    "keep the shard files next to the manifest (re-fetch: run scripts/setup)");
      }
      found += size;
    }
    check_group_size(source, g, groups[g], found);
    blobs[g].reserve(std::size_t(found));
    for (const auto& p : groups[g].paths) {
      const std::vector<std::byte> shard = read_file_bytes(dir / p, kOp);
      blobs[g].insert(blobs[g].end(), shard.begin(), shard.end());
    }
    // The files may have changed between the size check and the read.
    check_group_size(source, g, groups[g], blobs[g].size());
  }
  std::vector<std::span<const std::byte>> spans(blobs.begin(), blobs.end());
  return decode_all(groups, spans, source);
}

}  // namespace vkjr2::nets
