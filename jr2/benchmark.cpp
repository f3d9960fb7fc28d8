#include <vkjr2/jr2/benchmark.hpp>
#include <vkjr2/runtime/error.hpp>

#include <nlohmann/json.hpp>

#include <algorithm>
#include <charconv>
#include <cmath>
#include <fstream>
#include <map>
#include <set>
#include <sstream>

#include "internal/text_and_draws.hpp"

namespace vkjr2::jr2 {
namespace {

using ojson = nlohmann::ordered_json;

// SplitMix64: a probe's random numbers from (seed, index) alone.
std::uint64_t splitmix(std::uint64_t x) {
  return detail::splitmix_finalize(x + detail::kGoldenGamma);
}
using detail::unit_interval;

// Fisher–Yates with draws from SplitMix64 (the same on every platform).
template <class T>
void shuffle(std::vector<T>& v, std::uint64_t seed) {
  std::uint64_t state = seed;
  const auto next = [&state] { return splitmix(state++); };
  for (std::size_t i = v.size(); i > 1; --i) {
    std::swap(v[i - 1], v[std::size_t(detail::draw_below(next, i))]);
  }
}

// A file-name-safe form of an identity: [A-Za-z0-9._-] kept, the rest '_'.
std::string safe_name(const std::string& id) {
  std::string s;
  for (char c : id) {
    const bool ok = (c >= 'a' && c <= 'z') || (c >= 'A' && c <= 'Z') || (c >= '0' && c <= '9') ||
                    c == '.' || c == '_' || c == '-';
    s += ok ? c : '_';
  }
  if (s.empty() || s[0] == '.') s = "_" + s;
  return s;
}

std::string in_quotes(const std::string& s) { return "'" + s + "'"; }

[[noreturn]] void bad(const std::string& what, const std::string& problem,
                      const std::string& fix = "make the benchmark again with vkjr2 dataset make") {
  throw InvalidArgument("manifest", what + ": " + problem, fix);
}

const ojson& field(const ojson& j, const char* key, const std::string& what) {
  if (!j.is_object() || !j.contains(key)) bad(what, std::string("no field \"") + key + "\"");
  return j.at(key);
}
std::string get_string(const ojson& j, const char* key, const std::string& what) {
  const ojson& v = field(j, key, what);
  if (!v.is_string()) bad(what, std::string("\"") + key + "\" is not a string");
  return v.get<std::string>();
}
double get_number(const ojson& j, const char* key, const std::string& what) {
  const ojson& v = field(j, key, what);
  if (!v.is_number() || !std::isfinite(v.get<double>())) {
    bad(what, std::string("\"") + key + "\" is not a finite number");
  }
  return v.get<double>();
}
std::int64_t get_int(const ojson& j, const char* key, const std::string& what) {
  const ojson& v = field(j, key, what);
  if (!v.is_number_integer()) bad(what, std::string("\"") + key + "\" is not a whole number");
  return v.get<std::int64_t>();
}
std::uint64_t get_uint(const ojson& j, const char* key, const std::string& what) {
  const ojson& v = field(j, key, what);
  if (!v.is_number_unsigned()) bad(what, std::string("\"") + key + "\" is not a whole number ≥ 0");
  return v.get<std::uint64_t>();
}
bool get_bool(const ojson& j, const char* key, const std::string& what) {
  const ojson& v = field(j, key, what);
  if (!v.is_boolean()) bad(what, std::string("\"") + key + "\" is not true or false");
  return v.get<bool>();
}

ojson source_json(const SourceImage& s) {
  return ojson{{"identity", s.identity}, {"path", s.path}, {"face", s.face}};
}
SourceImage source_from(const ojson& j, const std::string& what) {
  return {get_string(j, "identity", what), get_string(j, "path", what),
          int(get_int(j, "face", what))};
}

// The plan's parameters without its items (shards of one plan share them).
ojson header_json(const Manifest& m) {
  const BenchmarkOptions& o = m.options;
  ojson strengths = ojson::array();
  for (const StrengthRange& s : o.strengths) {
    strengths.push_back(ojson{{"name", s.name}, {"d_over_r0", {s.d_over_r0_lo, s.d_over_r0_hi}}});
  }
  ojson skipped = ojson::array();
  for (const auto& [file, why] : m.skipped) skipped.push_back(ojson{{"file", file}, {"why", why}});
  return ojson{{"format", "vkjr2-benchmark"},
               {"version", m.version},
               {"source", {{"kind", m.source_kind}, {"root", m.source_root}}},
               {"identities", m.identities},
               {"split_kind", m.split_kind == SplitKind::identity ? "identity" : "realization"},
               {"seed", o.seed},
               {"frames", o.frames},
               {"clip_size", o.clip_size},
               {"face_px", o.face_px},
               {"probes_per_identity", o.probes},
               {"enrolled_share", o.enrolled},
               {"val_share", o.val_share},
               {"min_split_identities", o.min_split_identities},
               {"strengths", strengths},
               {"skipped", skipped}};
}

void check_options(const BenchmarkOptions& o) {
  const auto fail = [](const std::string& p, const std::string& fix) {
    throw InvalidArgument("plan_benchmark", p, fix);
  };
  if (o.strengths.empty())
    fail("no turbulence strength", "name at least one (weak, moderate, strong)");
  for (const StrengthRange& s : o.strengths) {
    if (!(s.d_over_r0_lo > 0 && s.d_over_r0_hi >= s.d_over_r0_lo && s.d_over_r0_hi <= 50)) {
      fail("strength " + s.name + " has D/r0 range [" + std::to_string(s.d_over_r0_lo) + ", " +
               std::to_string(s.d_over_r0_hi) + "]",
           "use 0 < lo ≤ hi ≤ 50");
    }
  }
  if (o.frames < 1 || o.frames > 10000)
    fail("frames = " + std::to_string(o.frames), "use 1..10000");
  if (o.clip_size < 32 || o.clip_size > 1024 || o.face_px < 8 || o.face_px > o.clip_size) {
    fail("clip " + std::to_string(o.clip_size) + " px with faces of " + std::to_string(o.face_px) +
             " px",
         "use a clip of 32..1024 px and a face of 8 px up to the clip's size");
  }
  if (o.probes < 1 || o.probes > 1000) fail("probes = " + std::to_string(o.probes), "use 1..1000");
  if (!(o.enrolled > 0 && o.enrolled <= 1)) {
    fail("enrolled share " + std::to_string(o.enrolled), "use a share in (0, 1]");
  }
  if (!(o.val_share > 0 && o.val_share < 1)) {
    fail("val share " + std::to_string(o.val_share), "use a share in (0, 1)");
  }
}

}  // namespace

std::vector<StrengthRange> default_strengths() {
  return {{"weak", 1.0, 2.0}, {"moderate", 2.0, 4.0}, {"strong", 4.0, 8.0}};
}

std::vector<StrengthRange> parse_strengths(const std::string& names) {
  const std::vector<StrengthRange> known = default_strengths();
  std::vector<StrengthRange> out;
  std::stringstream ss(names);
  std::string name;
  while (std::getline(ss, name, ',')) {
    const auto it = std::find_if(known.begin(), known.end(),
                                 [&](const StrengthRange& s) { return s.name == name; });
    if (it == known.end()) {
      throw InvalidArgument("strengths",
                            in_quotes(name) + " in " + in_quotes(names) + " is unknown",
                            "use a comma-separated list of weak, moderate, strong");
    }
    if (std::any_of(out.begin(), out.end(),
                    [&](const StrengthRange& s) { return s.name == name; })) {
      throw InvalidArgument("strengths", in_quotes(name) + " is named twice in " + in_quotes(names),
                            "name each strength once");
    }
    out.push_back(*it);
  }
  if (out.empty()) {
    throw InvalidArgument("strengths", "no strength named",
                          "use a comma-separated list of weak, moderate, strong");
  }
  return out;
}

Manifest plan_benchmark(const std::vector<SourceImage>& images, const BenchmarkOptions& o) {
  check_options(o);
  std::map<std::string, std::vector<SourceImage>> by_id;
  for (const SourceImage& s : images) by_id[s.identity].push_back(s);
  if (by_id.size() < 2) {
    throw InvalidArgument("plan_benchmark",
                          "the source has " + std::to_string(by_id.size()) + " identities",
                          "a benchmark needs at least 2 (one enrolled, one more to compare with)");
  }
  Manifest m;
  m.options = o;
  m.identities = by_id.size();
  std::vector<std::string> ids;
  for (const auto& [id, imgs] : by_id) ids.push_back(id);
  // File names: safe, and distinct even when two identities map to one.
  std::map<std::string, std::string> file_id;
  std::set<std::string> used;
  for (const std::string& id : ids) {
    std::string name = safe_name(id);
    for (int k = 2; used.count(name) != 0; ++k) name = safe_name(id) + "-" + std::to_string(k);
    used.insert(name);
    file_id[id] = name;
  }

  const auto n = std::int64_t(ids.size());
  const auto n_val = std::int64_t(std::llround(double(n) * o.val_share));
  m.split_kind = (n_val >= o.min_split_identities && n - n_val >= o.min_split_identities)
                     ? SplitKind::identity
                     : SplitKind::realization;
  std::vector<std::string> order = ids;
  shuffle(order, splitmix(o.seed ^ 0x5eedULL));
  std::map<std::string, std::string> split_of;  // identity → "val"/"test"/"all"
  std::map<std::string, bool> enrolled;
  const auto enrol = [&](const std::vector<std::string>& group) {
    auto k = std::int64_t(std::floor(double(group.size()) * o.enrolled + 1e-9));
    k = std::clamp<std::int64_t>(k, 1, std::int64_t(group.size()));
    for (std::size_t i = 0; i < group.size(); ++i) enrolled[group[i]] = std::int64_t(i) < k;
  };
  if (m.split_kind == SplitKind::identity) {
    std::vector<std::string> val(order.begin(), order.begin() + n_val);
    std::vector<std::string> test(order.begin() + n_val, order.end());
    for (const auto& id : val) split_of[id] = "val";
    for (const auto& id : test) split_of[id] = "test";
    enrol(val);
    enrol(test);
  } else {
    for (const auto& id : order) split_of[id] = "all";
    enrol(order);
  }

  for (const std::string& id : ids) {
    if (!enrolled[id]) continue;
    m.gallery.push_back({id, split_of[id], "gallery/" + file_id[id] + ".png", by_id[id].front()});
  }
  std::uint64_t index = 0;
  for (const char* split : {"val", "test"}) {
    for (const StrengthRange& st : o.strengths) {
      for (const std::string& id : ids) {
        if (split_of[id] != "all" && split_of[id] != split) continue;
        const std::vector<SourceImage>& imgs = by_id[id];
        for (int k = 0; k < o.probes; ++k, ++index) {
          ProbeItem p;
          p.identity = id;
          p.mated = enrolled[id];
          p.split = split;
          p.strength = st.name;
          const std::uint64_t r = splitmix(splitmix(o.seed) + index);
          const double u = unit_interval(splitmix(r ^ 0xd0d0ULL));
          p.d_over_r0 = st.d_over_r0_lo * std::pow(st.d_over_r0_hi / st.d_over_r0_lo, u);
          p.seed = r;
          // Mated probes come from the identity's other images when it has any.
          if (p.mated && imgs.size() > 1) {
            p.source = imgs[1 + std::size_t(k) % (imgs.size() - 1)];
          } else {
            p.source = imgs[std::size_t(k) % imgs.size()];
            p.same_image_as_gallery = p.mated;
          }
          const std::string stem = "probes/" + std::string(split) + "/" + st.name + "/" +
                                   file_id[id] + "_" + std::to_string(k);
          p.file = stem + ".avi";
          p.clean_file = stem + "_clean.png";
          m.probes.push_back(std::move(p));
        }
      }
    }
  }
  return m;
}

Manifest shard_of(const Manifest& plan, int index, int count) {
  if (count < 1 || index < 0 || index >= count) {
    throw InvalidArgument("shard_of",
                          "shard " + std::to_string(index) + "/" + std::to_string(count),
                          "use I/N with 0 ≤ I < N");
  }
  Manifest m = plan;
  m.gallery.clear();
  m.probes.clear();
  m.shard_index = index;
  m.shard_count = count;
  std::size_t pos = 0;
  for (const GalleryItem& g : plan.gallery) {
    if (int(pos++ % std::size_t(count)) == index) m.gallery.push_back(g);
  }
  for (const ProbeItem& p : plan.probes) {
    if (int(pos++ % std::size_t(count)) == index) m.probes.push_back(p);
  }
  return m;
}

std::pair<int, int> parse_shard(const std::string& text) {
  const std::size_t slash = text.find('/');
  int i = -1, n = 0;
  bool ok = slash != std::string::npos;
  if (ok) {
    const auto a = std::from_chars(text.data(), text.data() + slash, i);
    const auto b = std::from_chars(text.data() + slash + 1, text.data() + text.size(), n);
    ok = a.ec == std::errc() && a.ptr == text.data() + slash && b.ec == std::errc() &&
         b.ptr == text.data() + text.size() && n >= 1 && i >= 0 && i < n;
  }
  if (!ok) {
    throw InvalidArgument("--shard", "'" + text + "' is not a shard",
                          "write I/N with 0 ≤ I < N, e.g. --shard 0/4 (Slurm: "
                          "$SLURM_ARRAY_TASK_ID/$SLURM_ARRAY_TASK_COUNT)");
  }
  return {i, n};
}

Manifest merge_shards(const std::vector<Manifest>& shards) {
  if (shards.empty()) throw InvalidArgument("merge_shards", "no shard manifests", "pass all N");
  const int count = shards.front().shard_count;
  std::vector<const Manifest*> by_index(std::size_t(count), nullptr);
  const std::string header = header_json(shards.front()).dump();
  for (const Manifest& s : shards) {
    if (s.shard_count != count) {
      throw InvalidArgument("merge_shards",
                            "shards of " + std::to_string(count) + " and of " +
                                std::to_string(s.shard_count) + " parts",
                            "merge the shards of one run");
    }
    if (header_json(s).dump() != header) {
      throw InvalidArgument("merge_shards",
                            "shard " + std::to_string(s.shard_index) +
                                " was planned with other options, seed or source than shard " +
                                std::to_string(shards.front().shard_index),
                            "run every shard with the same options");
    }
    if (by_index[std::size_t(s.shard_index)] != nullptr) {
      throw InvalidArgument("merge_shards",
                            "shard " + std::to_string(s.shard_index) + " given twice",
                            "pass each shard's manifest once");
    }
    by_index[std::size_t(s.shard_index)] = &s;
  }
  for (int i = 0; i < count; ++i) {
    if (by_index[std::size_t(i)] == nullptr) {
      throw InvalidArgument("merge_shards",
                            "shard " + std::to_string(i) + " of " + std::to_string(count) +
                                " is missing (" + shard_manifest_name(i, count) + ")",
                            "run it (--shard " + std::to_string(i) + "/" + std::to_string(count) +
                                "), then merge again");
    }
  }
  Manifest m = *by_index[0];
  m.shard_index = 0;
  m.shard_count = 1;
  m.gallery.clear();
  m.probes.clear();
  std::size_t gallery = 0, total = 0;
  for (const Manifest* s : by_index) {
    gallery += s->gallery.size();
    total += s->gallery.size() + s->probes.size();
  }
  for (std::size_t pos = 0; pos < total; ++pos) {
    const Manifest& s = *by_index[pos % std::size_t(count)];
    const std::size_t local = pos / std::size_t(count);
    if (pos < gallery) {
      m.gallery.push_back(s.gallery.at(local));
    } else {
      m.probes.push_back(s.probes.at(local - s.gallery.size()));
    }
  }
  return m;
}

sim::Params probe_sim_params(double d_over_r0, int clip_size) {
  sim::Params p = sim::preset("moderate");
  p.path.strength = sim::Strength::r0;
  p.path.r0_m = p.optics.aperture_m / d_over_r0;
  p.path.r0_wavelength_m = p.optics.wavelengths_m.front();
  p.image = {clip_size, clip_size, 3, 1};
  (void)sim::derive(p);  // validates
  return p;
}

sim::SimOptions probe_sim_options() {
  sim::SimOptions o;
  o.field.tilt_rho = 0.9;
  o.field.high_order_rho = 0.6;
  return o;
}

std::string shard_manifest_name(int index, int count) {
  return "manifest.shard-" + std::to_string(index) + "-of-" + std::to_string(count) + ".json";
}

std::string manifest_json(const Manifest& m) {
  ojson j = header_json(m);
  if (m.shard_count > 1) j["shard"] = {{"index", m.shard_index}, {"count", m.shard_count}};
  ojson gallery = ojson::array();
  for (const GalleryItem& g : m.gallery) {
    gallery.push_back(ojson{{"file", g.file},
                            {"identity", g.identity},
                            {"split", g.split},
                            {"source", source_json(g.source)}});
  }
  ojson probes = ojson::array();
  for (const ProbeItem& p : m.probes) {
    probes.push_back(ojson{{"file", p.file},
                           {"clean_file", p.clean_file},
                           {"identity", p.identity},
                           {"mated", p.mated},
                           {"split", p.split},
                           {"strength", p.strength},
                           {"d_over_r0", p.d_over_r0},
                           {"seed", p.seed},
                           {"source", source_json(p.source)},
                           {"same_image_as_gallery", p.same_image_as_gallery}});
  }
  j["gallery"] = gallery;
  j["probes"] = probes;
  return j.dump(1) + "\n";
}

Manifest parse_manifest(const std::string& text, const std::string& what) {
  ojson j;
  try {
    j = ojson::parse(text);
  } catch (const std::exception& e) {
    bad(what, std::string("not JSON (") + e.what() + ")");
  }
  if (!j.is_object() || !j.contains("format") || j["format"] != "vkjr2-benchmark") {
    bad(what, "not a vkjr2 benchmark manifest (no \"format\": \"vkjr2-benchmark\")",
        "pass the manifest.json that vkjr2 dataset make wrote");
  }
  Manifest m;
  m.version = int(get_int(j, "version", what));
  if (m.version != 1) bad(what, "version " + std::to_string(m.version) + " (this vkjr2 reads 1)");
  const ojson& src = field(j, "source", what);
  m.source_kind = get_string(src, "kind", what + " source");
  m.source_root = get_string(src, "root", what + " source");
  m.identities = std::size_t(get_uint(j, "identities", what));
  const std::string sk = get_string(j, "split_kind", what);
  if (sk != "identity" && sk != "realization") bad(what, "split_kind '" + sk + "'");
  m.split_kind = sk == "identity" ? SplitKind::identity : SplitKind::realization;
  BenchmarkOptions& o = m.options;
  o.seed = get_uint(j, "seed", what);
  o.frames = int(get_int(j, "frames", what));
  o.clip_size = int(get_int(j, "clip_size", what));
  o.face_px = int(get_int(j, "face_px", what));
  o.probes = int(get_int(j, "probes_per_identity", what));
  o.enrolled = get_number(j, "enrolled_share", what);
  o.val_share = get_number(j, "val_share", what);
  o.min_split_identities = int(get_int(j, "min_split_identities", what));
  o.strengths.clear();
  const ojson& strengths = field(j, "strengths", what);
  if (!strengths.is_array()) bad(what, "\"strengths\" is not a list");
  for (const ojson& s : strengths) {
    const ojson& r = field(s, "d_over_r0", what + " strength");
    if (!r.is_array() || r.size() != 2 || !r[0].is_number() || !r[1].is_number()) {
      bad(what, "a strength's \"d_over_r0\" is not [lo, hi]");
    }
    o.strengths.push_back(
        {get_string(s, "name", what + " strength"), r[0].get<double>(), r[1].get<double>()});
  }
  try {
    check_options(o);
  } catch (const InvalidArgument& e) {
    bad(what, e.problem());
  }
  const ojson& skipped = field(j, "skipped", what);
  if (!skipped.is_array()) bad(what, "\"skipped\" is not a list");
  for (const ojson& s : skipped) {
    m.skipped.emplace_back(get_string(s, "file", what), get_string(s, "why", what));
  }
  if (j.contains("shard")) {
    m.shard_index = int(get_int(j["shard"], "index", what));
    m.shard_count = int(get_int(j["shard"], "count", what));
    if (m.shard_count < 1 || m.shard_index < 0 || m.shard_index >= m.shard_count) {
      bad(what, "shard " + std::to_string(m.shard_index) + " of " + std::to_string(m.shard_count));
    }
  }
  std::set<std::string> strength_names, files;
  for (const StrengthRange& s : o.strengths) strength_names.insert(s.name);
  std::map<std::string, std::string> gallery_split;
  const auto check_file = [&](const std::string& file, const std::string& item) {
    const std::filesystem::path p(file);
    if (file.empty() || p.is_absolute() ||
        std::any_of(p.begin(), p.end(), [](const auto& part) { return part == ".."; })) {
      bad(item, "file '" + file + "' is not a path inside the benchmark folder");
    }
    if (!files.insert(file).second) bad(item, "file '" + file + "' is listed twice");
  };
  const ojson& gallery = field(j, "gallery", what);
  if (!gallery.is_array()) bad(what, "\"gallery\" is not a list");
  for (std::size_t i = 0; i < gallery.size(); ++i) {
    const std::string item = what + " gallery[" + std::to_string(i) + "]";
    GalleryItem g{get_string(gallery[i], "identity", item), get_string(gallery[i], "split", item),
                  get_string(gallery[i], "file", item),
                  source_from(field(gallery[i], "source", item), item)};
    if (g.split != "val" && g.split != "test" && g.split != "all") {
      bad(item, "split '" + g.split + "' (a gallery item is in val, test or all)");
    }
    check_file(g.file, item);
    if (!gallery_split.emplace(g.identity, g.split).second) {
      bad(item, "identity '" + g.identity + "' is enrolled twice");
    }
    m.gallery.push_back(std::move(g));
  }
  const ojson& probes = field(j, "probes", what);
  if (!probes.is_array()) bad(what, "\"probes\" is not a list");
  for (std::size_t i = 0; i < probes.size(); ++i) {
    const ojson& pj = probes[i];
    const std::string item = what + " probes[" + std::to_string(i) + "]";
    ProbeItem p;
    p.file = get_string(pj, "file", item);
    p.clean_file = get_string(pj, "clean_file", item);
    p.identity = get_string(pj, "identity", item);
    p.mated = get_bool(pj, "mated", item);
    p.split = get_string(pj, "split", item);
    p.strength = get_string(pj, "strength", item);
    p.d_over_r0 = get_number(pj, "d_over_r0", item);
    p.seed = get_uint(pj, "seed", item);
    p.source = source_from(field(pj, "source", item), item);
    p.same_image_as_gallery = get_bool(pj, "same_image_as_gallery", item);
    if (p.split != "val" && p.split != "test")
      bad(item, "split '" + p.split + "' (a probe is in val or test)");
    if (strength_names.count(p.strength) == 0)
      bad(item, "strength '" + p.strength + "' is not among the manifest's strengths");
    check_file(p.file, item);
    check_file(p.clean_file, item);
    if (m.shard_count == 1) {
      const auto g = gallery_split.find(p.identity);
      if (p.mated && g == gallery_split.end()) {
        bad(item, "mated probe of '" + p.identity + "', who has no gallery image");
      }
      if (p.mated && g->second != "all" && g->second != p.split) {
        bad(item, "probe in " + p.split + " of '" + p.identity + "', enrolled in " + g->second +
                      " (splits must not share identities)");
      }
      if (!p.mated && g != gallery_split.end()) {
        bad(item, "non-mated probe of '" + p.identity + "', who is enrolled");
      }
    }
    m.probes.push_back(std::move(p));
  }
  return m;
}

Manifest read_manifest(const std::filesystem::path& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) {
    throw Error("read_manifest", "cannot open " + path.string(),
                "pass the manifest.json that vkjr2 dataset make wrote");
  }
  std::stringstream ss;
  ss << in.rdbuf();
  return parse_manifest(ss.str(), path.string());
}

std::string manifest_csv(const Manifest& m) {
  std::ostringstream out;
  out << "kind,file,identity,mated,split,strength,d_over_r0,seed,source,face,same_image_as_"
         "gallery\n";
  for (const GalleryItem& g : m.gallery) {
    out << "gallery," << detail::csv_field(g.file) << "," << detail::csv_field(g.identity) << ",,"
        << g.split << ",,,," << detail::csv_field(g.source.path) << "," << g.source.face << ",\n";
  }
  char d[32];
  for (const ProbeItem& p : m.probes) {
    std::snprintf(d, sizeof d, "%.6f", p.d_over_r0);
    out << "probe," << detail::csv_field(p.file) << "," << detail::csv_field(p.identity) << ","
        << (p.mated ? 1 : 0) << "," << p.split << "," << p.strength << "," << d << "," << p.seed
        << "," << detail::csv_field(p.source.path) << "," << p.source.face << ","
        << (p.same_image_as_gallery ? 1 : 0) << "\n";
  }
  return out.str();
}

void check_manifest_files(const Manifest& m, const std::filesystem::path& dir) {
  std::error_code ec;
  const auto check = [&](const std::string& file) {
    if (!std::filesystem::is_regular_file(dir / file, ec)) {
      throw Error("benchmark", (dir / file).string() + ", listed in the manifest, is missing",
                  "make the benchmark again (vkjr2 dataset make), or finish its shards and merge");
    }
  };
  for (const GalleryItem& g : m.gallery) check(g.file);
  for (const ProbeItem& p : m.probes) {
    check(p.file);
    check(p.clean_file);
  }
}

}  // namespace vkjr2::jr2
