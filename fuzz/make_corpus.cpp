// Writes the seed corpus for the fuzz targets with the library's own writers:
//   make_corpus DIR   ->  DIR/safetensors/*, DIR/npy/*, DIR/tfjs/*
// The files are small and committed under fuzz/corpus/; re-run this after a
// format change.
#include <vkjr2/nets/safetensors.hpp>
#include <vkjr2/runtime/npy.hpp>

#include <cstdint>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <string>
#include <vector>

namespace {

namespace fs = std::filesystem;
using namespace vkjr2;
using namespace vkjr2::nets;

std::vector<std::byte> bytes_of(const std::string& s) {
  std::vector<std::byte> out(s.size());
  std::memcpy(out.data(), s.data(), s.size());
  return out;
}

template <typename T>
std::string raw(std::initializer_list<T> values) {
  return std::string(reinterpret_cast<const char*>(std::data(values)), values.size() * sizeof(T));
}

// .npy with another dtype or version than write_npy produces.
std::string npy(const std::string& descr, const std::string& shape, const std::string& data,
                int major) {
  std::string dict = "{'descr': '" + descr + "', 'fortran_order': False, 'shape': " + shape + ", }";
  const std::size_t prefix = major == 1 ? 10 : 12;
  const std::size_t total = (prefix + dict.size() + 1 + 63) / 64 * 64;
  dict.append(total - prefix - dict.size() - 1, ' ');
  dict += '\n';
  std::string out = "\x93NUMPY";
  out += char(major);
  out += '\0';
  const std::uint32_t n = std::uint32_t(dict.size());
  out.append(reinterpret_cast<const char*>(&n), prefix - 8);
  return out + dict + data;
}

// The tfjs_fuzz framing: u16 manifest length, manifest, then u32-prefixed groups.
std::string tfjs(const std::string& manifest, const std::vector<std::string>& groups) {
  std::string out;
  const std::uint16_t m = std::uint16_t(manifest.size());
  out.append(reinterpret_cast<const char*>(&m), 2);
  out += manifest;
  for (const auto& g : groups) {
    const std::uint32_t n = std::uint32_t(g.size());
    out.append(reinterpret_cast<const char*>(&n), 4);
    out += g;
  }
  return out;
}

}  // namespace

int main(int argc, char** argv) {
  if (argc != 2) {
    std::fprintf(stderr, "usage: make_corpus DIR\n");
    return 2;
  }
  const fs::path dir = argv[1];
  for (const char* sub : {"safetensors", "npy", "tfjs"}) fs::create_directories(dir / sub);
  try {
    // safetensors
    const std::vector<float> w = {0.5f, -1.f, 2.f, 0.25f, -3.f, 1e-3f};
    write_safetensors(dir / "safetensors/f32.safetensors",
                      std::vector<SafetensorsRecord>{SafetensorsRecord::f32("w", {2, 3}, w)},
                      {{"format", "pt"}});
    std::vector<SafetensorsRecord> mixed;
    mixed.push_back(SafetensorsRecord::f32("layer/weight", {3, 2}, w));
    mixed.push_back(SafetensorsRecord::i32("adam/step", {}, std::vector<std::int32_t>{17}));
    mixed.push_back(
        SafetensorsRecord::u32("rng", {2}, std::vector<std::uint32_t>{7u, 0xdeadbeefu}));
    mixed.push_back({"h", StDType::F16, {2}, bytes_of(raw<std::uint16_t>({0x3c00, 0xc000}))});
    mixed.push_back({"b", StDType::BF16, {1}, bytes_of(raw<std::uint16_t>({0x3f80}))});
    mixed.push_back({"d", StDType::F64, {1}, bytes_of(raw<double>({0.1}))});
    mixed.push_back({"c", StDType::U8, {3}, bytes_of(raw<std::uint8_t>({1, 2, 3}))});
    mixed.push_back({"l", StDType::I64, {1}, bytes_of(raw<std::int64_t>({-5}))});
    mixed.push_back(SafetensorsRecord::f32("empty", {0, 4}, std::vector<float>{}));
    write_safetensors(dir / "safetensors/mixed.safetensors", mixed, {{"step", "17"}});
    write_safetensors(dir / "safetensors/none.safetensors", std::vector<SafetensorsRecord>{});

    // npy
    write_npy(dir / "npy/f32_hwc.npy", HostTensor{{2, 1, 3}, {0, 1, 2, 253, 254, 255}});
    write_npy(dir / "npy/scalar.npy", HostTensor{{}, {4.5f}});
    write_file_atomic(dir / "npy/u1.npy",
                      bytes_of(npy("|u1", "(2, 2)", raw<std::uint8_t>({0, 1, 2, 255}), 1)),
                      "make_corpus");
    write_file_atomic(dir / "npy/i4_v2.npy",
                      bytes_of(npy("<i4", "(3,)", raw<std::int32_t>({-1, 0, 1}), 2)),
                      "make_corpus");
    write_file_atomic(dir / "npy/f8_v3.npy",
                      bytes_of(npy("<f8", "(1, 2)", raw<double>({0.5, -2.0}), 3)), "make_corpus");

    // tfjs
    const std::string one_group = R"([{"paths":["a.bin"],"weights":[
{"name":"conv/filters","shape":[1,1,2,2],"dtype":"float32"},
{"name":"conv/bias","shape":[2],"dtype":"float32","quantization":{"dtype":"uint8","scale":0.5,"min":-1}},
{"name":"fc/w","shape":[2],"dtype":"float32","quantization":{"dtype":"uint16","scale":0.001,"min":0}},
{"name":"fc/b","shape":[2],"dtype":"float32","quantization":{"dtype":"float16"}},
{"name":"idx","shape":[],"dtype":"int32"}]}])";
    const std::string g = raw<float>({1, 2, 3, 4}) + raw<std::uint8_t>({0, 255}) +
                          raw<std::uint16_t>({7, 65535}) + raw<std::uint16_t>({0x3c00, 0x7c00}) +
                          raw<std::int32_t>({-3});
    write_file_atomic(dir / "tfjs/one_group.bin", bytes_of(tfjs(one_group, {g})), "make_corpus");
    const std::string two_groups =
        R"([{"paths":["a.bin","b.bin"],"weights":[{"name":"a","shape":[2],"dtype":"float32"}]},
{"paths":["c.bin"],"weights":[{"name":"b","shape":[3],"dtype":"int32","quantization":{"dtype":"uint8","scale":2,"min":1}}]}])";
    write_file_atomic(
        dir / "tfjs/two_groups.bin",
        bytes_of(tfjs(two_groups, {raw<float>({-1, 1}), raw<std::uint8_t>({0, 1, 2})})),
        "make_corpus");
  } catch (const std::exception& e) {
    std::fprintf(stderr, "make_corpus: %s\n", e.what());
    return 1;
  }
  return 0;
}
