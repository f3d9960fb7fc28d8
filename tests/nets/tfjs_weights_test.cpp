#include <vkjr2/nets/tfjs_weights.hpp>

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <cmath>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <string>

#include "support/temp_dir.hpp"

namespace vkjr2::nets {
namespace {

namespace fs = std::filesystem;

fs::path model_dir() {
  const char* env = std::getenv("VKJR2_CACHE_DIR");
  const char* home = std::getenv("HOME");
  const fs::path cache = env && *env ? fs::path(env) : fs::path(home ? home : "") / ".cache/vkjr2";
  return cache / "face-api-1.7.15" / "model";
}

void write_text(const fs::path& p, std::string_view s) {
  std::ofstream out(p, std::ios::binary);
  out.write(s.data(), std::streamsize(s.size()));
}

template <typename T>
void append(std::string& blob, std::initializer_list<T> values) {
  for (T v : values) blob.append(reinterpret_cast<const char*>(&v), sizeof(T));
}

// Loads a real face-api model and checks it against the manifest and the raw
// shard bytes read here independently.
void check_real_model(const std::string& name, std::int64_t want_params, std::int64_t want_bytes,
                      int want_raw_f32) {
  const fs::path dir = model_dir();
  const fs::path manifest = dir / (name + "-weights_manifest.json");
  if (!fs::exists(manifest)) {
    FAIL() << "missing " << manifest << ": run scripts/setup (fetches @vladmandic/face-api)";
  }
  SCOPED_TRACE(name);
  const TfjsWeights w = load_tfjs_weights(manifest);

  std::ifstream in(manifest);
  const nlohmann::json m = nlohmann::json::parse(in);
  ASSERT_EQ(m.size(), 1u);
  std::string shard;
  for (const auto& p : m[0]["paths"]) {
    std::ifstream s(dir / p.get<std::string>(), std::ios::binary);
    shard.append(std::istreambuf_iterator<char>(s), {});
  }
  std::int64_t params = 0, offset = 0;
  int raw_f32 = 0;
  std::size_t k = 0;
  for (const auto& wj : m[0]["weights"]) {
    const std::string wname = wj["name"].get<std::string>();
    SCOPED_TRACE(wname);
    std::int64_t numel = 1;
    for (const auto& d : wj["shape"]) numel *= d.get<std::int64_t>();
    params += numel;
    ASSERT_LT(k, w.entries().size());
    EXPECT_EQ(w.entries()[k].first, wname) << "manifest order";
    const HostTensor& t = w.at(wname);
    EXPECT_EQ(t.shape, wj["shape"].get<std::vector<std::int64_t>>());
    ASSERT_EQ(std::int64_t(t.values.size()), numel);
    const bool quant = wj.contains("quantization");
    // First, middle and last element of every tensor, decoded by hand.
    for (std::int64_t i : {std::int64_t(0), numel / 2, numel - 1}) {
      float want = 0;
      if (quant) {
        ASSERT_EQ(wj["quantization"]["dtype"], "uint8");
        const auto q = std::uint8_t(shard.at(std::size_t(offset + i)));
        want = float(q * wj["quantization"]["scale"].get<double>() +
                     wj["quantization"]["min"].get<double>());
      } else {
        std::memcpy(&want, shard.data() + offset + 4 * i, 4);
      }
      EXPECT_EQ(t.values[std::size_t(i)], want) << "element " << i;
    }
    offset += quant ? numel : 4 * numel;
    raw_f32 += quant ? 0 : 1;
    ++k;
  }
  EXPECT_EQ(w.size(), k);
  EXPECT_EQ(offset, std::int64_t(shard.size()));
  EXPECT_EQ(w.parameter_count(), params);
  if (want_params >= 0) {
    EXPECT_EQ(params, want_params);
  }
  if (want_bytes >= 0) {
    EXPECT_EQ(std::int64_t(shard.size()), want_bytes);
  }
  if (want_raw_f32 >= 0) {
    EXPECT_EQ(raw_f32, want_raw_f32);
  }
}

TEST(TfjsWeights, FaceRecognitionModel) {
  // REFERENCES.md: 6,444,032 bytes, 5,614,592 parameters, 8 raw float32 tensors.
  check_real_model("face_recognition_model", 5'614'592, 6'444'032, 8);
}

TEST(TfjsWeights, TinyFaceDetectorModel) {
  check_real_model("tiny_face_detector_model", -1, -1, 0);
}

TEST(TfjsWeights, FaceLandmark68Model) { check_real_model("face_landmark_68_model", -1, -1, 0); }

TEST(TfjsWeights, DecodesEveryDTypeAcrossShardsAndGroups) {
  test::TempDir dir;
  // Group 0: two shards whose boundary falls inside a tensor.
  std::string g0;
  append<float>(g0, {1.5f, -2.f, 3.25f, 0.f});                  // f32 [2,2]
  append<std::uint8_t>(g0, {0, 1, 255});                        // uint8 [3]
  append<std::uint16_t>(g0, {0, 1000, 65535});                  // uint16 [3]
  append<std::uint16_t>(g0, {0x3c00, 0xc000, 0x3555, 0x7c00});  // float16 [4]
  append<std::int32_t>(g0, {-5, 1 << 20});                      // int32 [2]
  append<std::uint8_t>(g0, {3, 4});                             // int32 uint8-quantized [2]
  write_text(dir.path / "g0-1.bin", g0.substr(0, 9));
  write_text(dir.path / "g0-2.bin", g0.substr(9));
  std::string g1;
  append<float>(g1, {42.f});  // scalar
  write_text(dir.path / "g1.bin", g1);
  const std::string manifest = R"([
    {"paths": ["g0-1.bin", "g0-2.bin"], "weights": [
      {"name": "f", "shape": [2, 2], "dtype": "float32"},
      {"name": "q8", "shape": [3], "dtype": "float32",
       "quantization": {"dtype": "uint8", "scale": 0.5, "min": -1.0}},
      {"name": "q16", "shape": [3], "dtype": "float32",
       "quantization": {"dtype": "uint16", "scale": 0.001, "min": 2.0}},
      {"name": "h", "shape": [4], "dtype": "float32", "quantization": {"dtype": "float16"}},
      {"name": "i", "shape": [2], "dtype": "int32"},
      {"name": "iq", "shape": [2], "dtype": "int32",
       "quantization": {"dtype": "uint8", "scale": 0.5, "min": 0.2}}]},
    {"paths": ["g1.bin"], "weights": [{"name": "s", "shape": [], "dtype": "float32"}]}])";
  write_text(dir.path / "m.json", manifest);
  const TfjsWeights w = load_tfjs_weights(dir.path / "m.json");
  ASSERT_EQ(w.size(), 7u);
  EXPECT_EQ(w.entries()[0].first, "f");
  EXPECT_EQ(w.entries()[6].first, "s");
  EXPECT_EQ(w.at("f").values, (std::vector<float>{1.5f, -2.f, 3.25f, 0.f}));
  EXPECT_EQ(w.at("f").shape, (std::vector<std::int64_t>{2, 2}));
  EXPECT_EQ(w.at("q8").values, (std::vector<float>{-1.f, -0.5f, 126.5f}));
  EXPECT_EQ(w.at("q16").values,
            (std::vector<float>{2.f, float(1000 * 0.001 + 2.0), float(65535 * 0.001 + 2.0)}));
  EXPECT_EQ(w.at("h").values[0], 1.f);
  EXPECT_EQ(w.at("h").values[1], -2.f);
  EXPECT_NEAR(w.at("h").values[2], 1.f / 3.f, 1e-3f);
  EXPECT_TRUE(std::isinf(w.at("h").values[3]));
  EXPECT_EQ(w.at("i").values, (std::vector<float>{-5.f, 1048576.f}));
  EXPECT_EQ(w.at("iq").values, (std::vector<float>{2.f, 2.f}));  // round(1.7), round(2.2)
  EXPECT_EQ(w.at("s").values, (std::vector<float>{42.f}));
  EXPECT_TRUE(w.at("s").shape.empty());
  EXPECT_EQ(w.parameter_count(), 4 + 3 + 3 + 4 + 2 + 2 + 1);
  EXPECT_EQ(w.source(), (dir.path / "m.json").string());

  // The same through the in-memory entry point.
  const auto span = [](const std::string& s) {
    return std::span(reinterpret_cast<const std::byte*>(s.data()), s.size());
  };
  const std::vector<std::span<const std::byte>> groups = {span(g0), span(g1)};
  const TfjsWeights mem = parse_tfjs_weights(manifest, groups);
  EXPECT_EQ(mem.at("q16").values, w.at("q16").values);
}

TEST(TfjsWeights, MissingNameListsNearNames) {
  std::string blob;
  append<float>(blob, {1.f, 2.f});
  const std::string manifest = R"([{"paths": ["x.bin"], "weights": [
      {"name": "conv0/filters", "shape": [1], "dtype": "float32"},
      {"name": "conv0/bias", "shape": [1], "dtype": "float32"}]}])";
  const std::vector<std::span<const std::byte>> groups = {
      std::span(reinterpret_cast<const std::byte*>(blob.data()), blob.size())};
  const TfjsWeights w = parse_tfjs_weights(manifest, groups, "model.json");
  EXPECT_TRUE(w.contains("conv0/bias"));
  EXPECT_FALSE(w.contains("conv0/filter"));
  try {
    (void)w.at("conv0/filter");
    FAIL() << "no error";
  } catch (const InvalidArgument& e) {
    const std::string msg = e.what();
    EXPECT_NE(msg.find("'conv0/filter'"), std::string::npos) << msg;
    EXPECT_NE(msg.find("nearest: 'conv0/filters'"), std::string::npos) << msg;
    EXPECT_NE(msg.find("model.json"), std::string::npos) << msg;
  }
}

struct FileCase {
  const char* what;
  std::string manifest;
  std::size_t shard_bytes;  // written to "w.bin" unless SIZE_MAX (no file)
  const char* expect;
};

TEST(TfjsWeights, ErrorPaths) {
  const std::string f32x4 = R"({"name": "a", "shape": [4], "dtype": "float32"})";
  const auto group = [](const std::string& weights) {
    return R"([{"paths": ["w.bin"], "weights": [)" + weights + "]}]";
  };
  const std::vector<FileCase> cases = {
      {"truncated shard", group(f32x4 + R"(, {"name": "b", "shape": [2], "dtype": "float32"})"), 18,
       "holds 18 bytes but its 2 weights need 24 (truncated: 6 bytes missing; weight 'b'"},
      {"extra trailing bytes", group(f32x4), 20, "4 extra trailing bytes"},
      {"shape vs bytes", group(R"({"name": "a", "shape": [3, 3], "dtype": "float32"})"), 16,
       "need 36"},
      {"unknown dtype", group(R"({"name": "a", "shape": [4], "dtype": "complex64"})"), 16,
       "unknown dtype \"complex64\""},
      {"unknown quantization",
       group(
           R"({"name": "a", "shape": [4], "dtype": "float32", "quantization": {"dtype": "int4"}})"),
       16, "unknown quantization dtype \"int4\""},
      {"quantization without scale",
       group(
           R"({"name": "a", "shape": [4], "dtype": "float32", "quantization": {"dtype": "uint8"}})"),
       4, "without finite \"scale\" and \"min\""},
      {"negative dim", group(R"({"name": "a", "shape": [-4], "dtype": "float32"})"), 16,
       "non-negative integer"},
      {"overflowing shape",
       group(R"({"name": "a", "shape": [4294967296, 4294967296], "dtype": "float32"})"), 16,
       "more elements than the data can hold"},
      {"duplicate weight", group(f32x4 + "," + f32x4), 32, "'a' appears twice"},
      {"no paths", R"([{"weights": []}])", 0, "no \"paths\" array"},
      {"not an array", R"({"paths": []})", 0, "not a JSON array"},
      {"not json", "[{", 0, "not valid JSON"},
      {"missing shard", group(f32x4), SIZE_MAX, "shard 'w.bin' of group 0"},
  };
  for (const auto& c : cases) {
    SCOPED_TRACE(c.what);
    test::TempDir dir;
    write_text(dir.path / "m.json", c.manifest);
    if (c.shard_bytes != SIZE_MAX) write_text(dir.path / "w.bin", std::string(c.shard_bytes, '\0'));
    try {
      load_tfjs_weights(dir.path / "m.json");
      ADD_FAILURE() << "no error";
    } catch (const Error& e) {
      const std::string msg = e.what();
      EXPECT_NE(msg.find(c.expect), std::string::npos) << msg;
      EXPECT_NE(msg.find((dir.path / "m.json").string()), std::string::npos) << msg;
    }
  }
  test::TempDir dir;
  EXPECT_THROW(load_tfjs_weights(dir.path / "absent.json"), Error);
  // One byte block per group.
  EXPECT_THROW(parse_tfjs_weights(group(f32x4), {}), InvalidArgument);
}

}  // namespace
}  // namespace vkjr2::nets
