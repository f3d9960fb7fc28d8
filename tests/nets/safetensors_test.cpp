#include <vkjr2/nets/safetensors.hpp>

#include <gtest/gtest.h>

#include <bit>
#include <cstring>
#include <filesystem>
#include <string>

#include "support/temp_dir.hpp"

namespace vkjr2::nets {
namespace {

namespace fs = std::filesystem;

std::vector<std::byte> to_bytes(std::string_view s) {
  std::vector<std::byte> out(s.size());
  std::memcpy(out.data(), s.data(), s.size());
  return out;
}

// A file from a header text (not padded) and a data buffer.
std::vector<std::byte> make_file(std::string_view header, std::span<const std::byte> buffer) {
  std::vector<std::byte> out(8);
  const std::uint64_t n = header.size();
  std::memcpy(out.data(), &n, 8);
  const auto h = to_bytes(header);
  out.insert(out.end(), h.begin(), h.end());
  out.insert(out.end(), buffer.begin(), buffer.end());
  return out;
}

std::string error_of(std::span<const std::byte> bytes) {
  try {
    parse_safetensors(bytes, "case.safetensors");
  } catch (const InvalidArgument& e) {
    return e.what();
  }
  return "(no error)";
}

template <typename T>
std::vector<std::byte> raw(std::initializer_list<T> values) {
  std::vector<std::byte> out(values.size() * sizeof(T));
  std::memcpy(out.data(), std::data(values), out.size());
  return out;
}

TEST(Safetensors, ExactBytesOfASmallFile) {
  // What the reference writer produces for {"a": float32 [1, 2]}: compact
  // JSON, padded with spaces to a multiple of 8.
  const std::vector<float> v = {1.f, 2.f};
  const std::vector<SafetensorsRecord> recs = {SafetensorsRecord::f32("a", {2}, v)};
  const auto bytes = serialize_safetensors(recs);
  const std::string header = R"({"a":{"data_offsets":[0,8],"dtype":"F32","shape":[2]}})";
  std::string padded = header;
  padded.append((8 - padded.size() % 8) % 8, ' ');
  const auto expected = make_file(padded, raw<float>({1.f, 2.f}));
  ASSERT_EQ(bytes.size(), expected.size());
  EXPECT_EQ(std::memcmp(bytes.data(), expected.data(), bytes.size()), 0);
  std::uint64_t n = 0;
  std::memcpy(&n, bytes.data(), 8);
  EXPECT_EQ(n % 8, 0u);
}

TEST(Safetensors, RoundTripEveryDTypeWithMetadata) {
  test::TempDir dir;
  const fs::path path = dir.path / "all.safetensors";
  std::vector<SafetensorsRecord> recs;
  const std::vector<float> f = {0.5f, -1.25f, 3.f, 1e-8f, -0.f, 7.f};
  recs.push_back(SafetensorsRecord::f32("w/f32", {2, 3}, f));
  const std::vector<std::int32_t> i = {-7, 0, 2147483647};
  recs.push_back(SafetensorsRecord::i32("step/i32", {3}, i));
  const std::vector<std::uint32_t> u = {0xffffffffu, 1u};
  recs.push_back(SafetensorsRecord::u32("rng/u32", {1, 2}, u));
  recs.push_back(
      {"h/f16", StDType::F16, {4}, raw<std::uint16_t>({0x3c00, 0xc000, 0x7bff, 0x0001})});
  recs.push_back({"b/bf16", StDType::BF16, {2}, raw<std::uint16_t>({0x3f80, 0xc0a0})});
  recs.push_back({"d/f64", StDType::F64, {2}, raw<double>({0.1, -2.5})});
  recs.push_back({"c/u8", StDType::U8, {3}, raw<std::uint8_t>({0, 128, 255})});
  recs.push_back({"l/i64", StDType::I64, {1}, raw<std::int64_t>({-(std::int64_t(1) << 40)})});
  recs.push_back(SafetensorsRecord::f32("scalar", {}, std::vector<float>{42.f}));
  recs.push_back(SafetensorsRecord::f32("empty", {0, 5}, std::vector<float>{}));
  const std::map<std::string, std::string> meta = {{"format", "pt"}, {"step", "12"}};
  write_safetensors(path, recs, meta);

  const SafetensorsFile file = read_safetensors(path);
  EXPECT_EQ(file.metadata, meta);
  ASSERT_EQ(file.tensors.size(), recs.size());
  for (const auto& r : recs) {
    SCOPED_TRACE(r.name);
    const SafetensorsRecord& got = file.at(r.name);
    EXPECT_EQ(got.dtype, r.dtype);
    EXPECT_EQ(got.shape, r.shape);
    EXPECT_EQ(got.data, r.data);
  }
  EXPECT_EQ(file.at("step/i32").as_i32(), i);
  EXPECT_EQ(file.at("rng/u32").as_u32(), u);
  EXPECT_EQ(file.at("w/f32").to_float(), f);
  EXPECT_EQ(file.at("h/f16").to_float(), (std::vector<float>{1.f, -2.f, 65504.f, 0x1p-24f}));
  EXPECT_EQ(file.at("b/bf16").to_float(), (std::vector<float>{1.f, -5.f}));
  EXPECT_EQ(file.at("d/f64").to_float(), (std::vector<float>{0.1f, -2.5f}));
  EXPECT_EQ(file.at("c/u8").to_float(), (std::vector<float>{0.f, 128.f, 255.f}));
  EXPECT_EQ(file.at("l/i64").to_float(), (std::vector<float>{-1099511627776.f}));
  EXPECT_EQ(file.at("scalar").to_host().values, (std::vector<float>{42.f}));
  EXPECT_EQ(file.at("empty").numel(), 0);
  // Sorted by element size, so every tensor sits at a multiple of its size.
  const auto bytes = serialize_safetensors(recs, meta);
  std::uint64_t n = 0;
  std::memcpy(&n, bytes.data(), 8);
  EXPECT_EQ(n % 8, 0u);
  std::size_t offset = 0;
  for (const auto& t : parse_safetensors(bytes).tensors) {
    EXPECT_EQ(offset % st_dtype_size(t.dtype), 0u) << t.name;
    offset += t.data.size();
  }
  EXPECT_THROW(file.at("step/i32").as_u32(), InvalidArgument);
}

TEST(Safetensors, ReadsOtherWritersLayouts) {
  // Key order, whitespace and "__metadata__" placement as another writer
  // might choose; no padding; zero-size tensor between two others.
  const std::string header =
      "{ \"b\" : {\"dtype\":\"I32\",\"shape\":[1],\"data_offsets\":[8,12]},\n"
      "  \"__metadata__\": {\"k\": \"v\"},"
      "  \"z\": {\"shape\":[0],\"dtype\":\"F32\",\"data_offsets\":[8,8]},"
      "  \"a\": {\"data_offsets\":[0,8],\"shape\":[2],\"dtype\":\"F32\"} }";
  std::vector<std::byte> buffer = raw<float>({3.f, 4.f});
  const auto b = raw<std::int32_t>({-9});
  buffer.insert(buffer.end(), b.begin(), b.end());
  const auto file = parse_safetensors(make_file(header, buffer));
  ASSERT_EQ(file.tensors.size(), 3u);
  EXPECT_EQ(file.tensors[0].name, "a");
  EXPECT_EQ(file.at("a").to_float(), (std::vector<float>{3.f, 4.f}));
  EXPECT_EQ(file.at("b").as_i32(), (std::vector<std::int32_t>{-9}));
  EXPECT_EQ(file.metadata.at("k"), "v");
  EXPECT_EQ(file.find("nope"), nullptr);
  try {
    (void)file.at("nope");
    FAIL() << "no error";
  } catch (const InvalidArgument& e) {
    EXPECT_NE(std::string(e.what()).find("'nope'"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("'a'"), std::string::npos) << e.what();
  }
}

TEST(Safetensors, FloatMapConvenience) {
  test::TempDir dir;
  const fs::path path = dir.path / "m.safetensors";
  std::map<std::string, HostTensor> in;
  in["conv/w"] = HostTensor{{3, 3, 1, 2}, std::vector<float>(18)};
  for (std::size_t i = 0; i < 18; ++i) in["conv/w"].values[i] = float(i) * 0.25f - 2.f;
  in["conv/b"] = HostTensor{{2}, {1.f, -1.f}};
  write_safetensors_f32(path, in, {{"model", "test"}});
  const auto out = read_safetensors_f32(path);
  ASSERT_EQ(out.size(), 2u);
  EXPECT_EQ(out.at("conv/w").shape, in["conv/w"].shape);
  EXPECT_EQ(out.at("conv/w").values, in["conv/w"].values);
  EXPECT_EQ(out.at("conv/b").values, in["conv/b"].values);
}

struct BadCase {
  const char* what;
  std::string header;
  std::size_t buffer_bytes;
  const char* expect;  // substring of the message
};

TEST(Safetensors, RejectsMalformedHeaders) {
  const std::string f32_2 = R"("dtype":"F32","shape":[2])";
  const std::vector<BadCase> cases = {
      {"not json", "{\"a\": ", 0, "not valid JSON"},
      {"empty header is a valid file", "{}", 0, "(no error)"},
      {"array", "[1, 2]", 0, "does not start with '{'"},
      {"entry not object", R"({"a": 3})", 0, "not an object"},
      {"missing field", R"({"a": {"dtype":"F32","shape":[2]}})", 8, "lacks one of"},
      {"unknown dtype", R"({"a": {"dtype":"F7","shape":[2],"data_offsets":[0,8]}})", 8,
       "unsupported dtype"},
      {"negative dim", R"({"a": {"dtype":"F32","shape":[-2],"data_offsets":[0,8]}})", 8,
       "non-negative integer"},
      {"float dim", R"({"a": {"dtype":"F32","shape":[2.0],"data_offsets":[0,8]}})", 8,
       "non-negative integer"},
      {"overflowing shape",
       R"({"a": {"dtype":"F32","shape":[4294967296,4294967296,16],"data_offsets":[0,8]}})", 8,
       "more elements than the data can hold"},
      {"huge shape", R"({"a": {"dtype":"F32","shape":[1000000000],"data_offsets":[0,8]}})", 8,
       "more elements than the data can hold"},
      {"offsets past buffer", "{\"a\": {" + f32_2 + ",\"data_offsets\":[0,16]}}", 8,
       "lie outside the 8-byte data buffer"},
      {"offsets reversed", "{\"a\": {" + f32_2 + ",\"data_offsets\":[8,0]}}", 8, "lie outside"},
      {"offsets vs dtype x shape", "{\"a\": {" + f32_2 + ",\"data_offsets\":[0,4]}}", 8, "needs 8"},
      {"offsets not a pair", "{\"a\": {" + f32_2 + ",\"data_offsets\":[0]}}", 8,
       "not an array [begin, end]"},
      {"overlap",
       "{\"a\": {" + f32_2 + ",\"data_offsets\":[0,8]}, \"b\": {" + f32_2 +
           ",\"data_offsets\":[4,12]}}",
       12, "overlap tensor 'a'"},
      {"hole", "{\"a\": {" + f32_2 + ",\"data_offsets\":[4,12]}}", 12, "no holes"},
      {"trailing", "{\"a\": {" + f32_2 + ",\"data_offsets\":[0,8]}}", 12, "4 trailing bytes"},
      {"duplicate name",
       "{\"a\": {" + f32_2 + ",\"data_offsets\":[0,8]}, \"a\": {" + f32_2 +
           ",\"data_offsets\":[8,16]}}",
       16, "names 'a' twice"},
      {"metadata not strings", R"({"__metadata__": {"k": 1}})", 0, "not a string"},
      {"metadata not object", R"({"__metadata__": [1]})", 0, "not an object"},
  };
  for (const auto& c : cases) {
    SCOPED_TRACE(c.what);
    const std::vector<std::byte> buffer(c.buffer_bytes, std::byte{0});
    const std::string msg = error_of(make_file(c.header, buffer));
    EXPECT_NE(msg.find(c.expect), std::string::npos) << msg;
    if (std::string(c.expect) != "(no error)") {
      EXPECT_NE(msg.find("case.safetensors"), std::string::npos) << msg;
    }
  }
}

TEST(Safetensors, RejectsTruncatedFiles) {
  EXPECT_NE(error_of(to_bytes("abc")).find("shorter than the 8-byte header"), std::string::npos);
  std::vector<std::byte> big(16, std::byte{0});
  const std::uint64_t n = 1ull << 40;
  std::memcpy(big.data(), &n, 8);
  EXPECT_NE(error_of(big).find("exceeds the 8 bytes that follow"), std::string::npos);
  // A valid file cut at every length fails cleanly.
  const std::vector<float> v = {1.f, 2.f, 3.f};
  const std::vector<SafetensorsRecord> recs = {SafetensorsRecord::f32("x", {3}, v)};
  const auto bytes = serialize_safetensors(recs);
  for (std::size_t len = 0; len < bytes.size(); ++len) {
    EXPECT_THROW(parse_safetensors(std::span(bytes).first(len)), InvalidArgument) << len;
  }
}

TEST(Safetensors, ErrorsNameTheFileAndTensor) {
  test::TempDir dir;
  const fs::path path = dir.path / "bad.safetensors";
  const auto bytes = make_file(R"({"layer1/w": {"dtype":"F32","shape":[3],"data_offsets":[0,8]}})",
                               std::vector<std::byte>(8));
  write_file_atomic(path, bytes, "test");
  try {
    read_safetensors(path);
    FAIL() << "no error";
  } catch (const InvalidArgument& e) {
    const std::string msg = e.what();
    EXPECT_NE(msg.find(path.string()), std::string::npos) << msg;
    EXPECT_NE(msg.find("'layer1/w'"), std::string::npos) << msg;
    EXPECT_NE(msg.find("needs 12"), std::string::npos) << msg;
  }
  EXPECT_THROW(read_safetensors(dir.path / "missing.safetensors"), Error);
}

TEST(Safetensors, WriteIsAtomicAndValidatesRecords) {
  test::TempDir dir;
  const fs::path path = dir.path / "ckpt.safetensors";
  const std::vector<float> v = {1.f};
  const std::vector<SafetensorsRecord> good = {SafetensorsRecord::f32("a", {1}, v)};
  write_safetensors(path, good);
  const auto before = read_file_bytes(path, "test");

  std::vector<SafetensorsRecord> dup = {good[0], good[0]};
  EXPECT_THROW(write_safetensors(path, dup), InvalidArgument);
  std::vector<SafetensorsRecord> mismatched = {{"m", StDType::F32, {2}, raw<float>({1.f})}};
  EXPECT_THROW(write_safetensors(path, mismatched), InvalidArgument);
  std::vector<SafetensorsRecord> reserved = {SafetensorsRecord::f32("__metadata__", {1}, v)};
  EXPECT_THROW(write_safetensors(path, reserved), InvalidArgument);
  std::vector<SafetensorsRecord> bad_utf8 = {SafetensorsRecord::f32("\xff\xfe", {1}, v)};
  EXPECT_THROW(write_safetensors(path, bad_utf8), InvalidArgument);
  EXPECT_THROW(SafetensorsRecord::f32("n", {3}, v), InvalidArgument);
  // Unwritable destination: nothing left behind.
  EXPECT_THROW(write_safetensors(dir.path / "no_such_dir" / "x.safetensors", good), Error);

  EXPECT_EQ(read_file_bytes(path, "test"), before);
  std::size_t files = 0;
  for ([[maybe_unused]] const auto& e : fs::directory_iterator(dir.path)) ++files;
  EXPECT_EQ(files, 1u) << "a temporary file was left behind";
}

}  // namespace
}  // namespace vkjr2::nets
