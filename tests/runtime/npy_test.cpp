#include <vkjr2/runtime/npy.hpp>

#include <gtest/gtest.h>
#include <unistd.h>

#include <cmath>
#include <cstring>
#include <filesystem>
#include <string>

namespace vkjr2 {
namespace {

namespace fs = std::filesystem;

// An .npy file from a header dict text (padded here like numpy does) and data.
std::vector<std::byte> make_npy(std::string dict, const std::string& data, int major = 1) {
  const std::size_t prefix = major == 1 ? 10 : 12;
  const std::size_t total = (prefix + dict.size() + 1 + 63) / 64 * 64;
  dict.append(total - prefix - dict.size() - 1, ' ');
  dict += '\n';
  std::string out = "\x93NUMPY";
  out += char(major);
  out += '\0';
  const std::uint32_t n = std::uint32_t(dict.size());
  out.append(reinterpret_cast<const char*>(&n), prefix - 8);
  out += dict;
  out += data;
  std::vector<std::byte> bytes(out.size());
  std::memcpy(bytes.data(), out.data(), out.size());
  return bytes;
}

template <typename T>
std::string raw(std::initializer_list<T> values) {
  return std::string(reinterpret_cast<const char*>(std::data(values)), values.size() * sizeof(T));
}

std::string error_of(std::span<const std::byte> bytes) {
  try {
    parse_npy(bytes, "img.npy");
  } catch (const InvalidArgument& e) {
    return e.what();
  }
  return "(no error)";
}

TEST(Npy, ExactBytesOfAnArrayNumpyWrites) {
  // What np.save writes for np.arange(6, dtype='<f4').reshape(2, 3): version
  // 1.0, the dict padded with spaces and a newline so that the 10-byte prefix
  // plus header is a multiple of 64.
  const HostTensor t{{2, 3}, {0, 1, 2, 3, 4, 5}};
  const auto bytes = serialize_npy(t);
  // 10 + 60-byte dict + '\n' rounds up to 128.
  ASSERT_EQ(bytes.size(), 128u + 24u);
  const std::string head(reinterpret_cast<const char*>(bytes.data()), 128);
  EXPECT_EQ(head.substr(0, 8), std::string("\x93NUMPY\x01\x00", 8));
  EXPECT_EQ(std::uint8_t(head[8]) | (std::uint8_t(head[9]) << 8), 118);
  const std::string dict = "{'descr': '<f4', 'fortran_order': False, 'shape': (2, 3), }";
  EXPECT_EQ(head.substr(10), dict + std::string(117 - dict.size(), ' ') + "\n");
  float v[6];
  std::memcpy(v, bytes.data() + 128, 24);
  EXPECT_EQ(std::vector<float>(v, v + 6), t.values);
}

TEST(Npy, RoundTripRanks) {
  const fs::path dir = fs::temp_directory_path() / ("vkjr2_npy_" + std::to_string(::getpid()));
  fs::create_directories(dir);
  const std::vector<HostTensor> cases = {{{}, {3.5f}},
                                         {{4}, {1, -2, 3, -4}},
                                         {{0, 3}, {}},
                                         {{2, 1, 2, 1, 2}, {1, 2, 3, 4, 5, 6, 7, 8}}};
  for (const auto& t : cases) {
    SCOPED_TRACE(shape_str(t.shape));
    const fs::path path = dir / "a.npy";
    write_npy(path, t);
    const HostTensor back = read_npy(path);
    EXPECT_EQ(back.shape, t.shape);
    EXPECT_EQ(back.values, t.values);
    EXPECT_EQ(fs::file_size(path) % 64, (t.values.size() * 4) % 64);
  }
  EXPECT_THROW(write_npy(dir / "bad.npy", HostTensor{{3}, {1.f}}), InvalidArgument);
  EXPECT_FALSE(fs::exists(dir / "bad.npy"));
  fs::remove_all(dir);
}

TEST(Npy, ReadsEveryDTypeAndVersion) {
  const auto f4 = parse_npy(make_npy("{'descr': '<f4', 'fortran_order': False, 'shape': (2,), }",
                                     raw<float>({1.5f, -2.f})));
  EXPECT_EQ(f4.values, (std::vector<float>{1.5f, -2.f}));
  const auto f8 = parse_npy(make_npy("{'descr': '<f8', 'fortran_order': False, 'shape': (1, 2), }",
                                     raw<double>({0.1, 1e300})));
  EXPECT_EQ(f8.values[0], 0.1f);
  EXPECT_TRUE(std::isinf(f8.values[1]));
  const auto u1 =
      parse_npy(make_npy("{'descr': '|u1', 'fortran_order': False, 'shape': (1, 1, 3), }",
                         raw<std::uint8_t>({0, 128, 255})));
  EXPECT_EQ(u1.values, (std::vector<float>{0.f, 128.f, 255.f}));
  EXPECT_EQ(u1.shape, (std::vector<std::int64_t>{1, 1, 3}));
  const auto i4 = parse_npy(make_npy("{'descr': '<i4', 'fortran_order': False, 'shape': (2,), }",
                                     raw<std::int32_t>({-7, 123456})));
  EXPECT_EQ(i4.values, (std::vector<float>{-7.f, 123456.f}));
  // Version 2.0/3.0 (u32 header length), other key order, double quotes, a
  // Python 2 long, no trailing comma.
  for (int major : {2, 3}) {
    const auto v2 =
        parse_npy(make_npy(R"({"shape": (3L,), "fortran_order": False, "descr": "<f4"})",
                           raw<float>({1, 2, 3}), major));
    EXPECT_EQ(v2.values, (std::vector<float>{1, 2, 3}));
  }
  const auto scalar = parse_npy(
      make_npy("{'descr': '<f4', 'fortran_order': False, 'shape': (), }", raw<float>({9})));
  EXPECT_TRUE(scalar.shape.empty());
  EXPECT_EQ(scalar.values, (std::vector<float>{9}));
}

TEST(Npy, RejectsBadFiles) {
  const std::string ok = "{'descr': '<f4', 'fortran_order': False, 'shape': (2,), }";
  const std::string data = raw<float>({1, 2});
  struct Case {
    const char* what;
    std::vector<std::byte> bytes;
    const char* expect;
  };
  auto with = [&](std::string dict) { return make_npy(std::move(dict), data); };
  std::vector<std::byte> bad_magic = with(ok);
  bad_magic[1] = std::byte{'X'};
  std::vector<std::byte> bad_version = with(ok);
  bad_version[6] = std::byte{9};
  std::vector<std::byte> long_header = with(ok);
  long_header[8] = std::byte{0xff};
  long_header[9] = std::byte{0x7f};
  const std::vector<Case> cases = {
      {"magic", bad_magic, "does not start with the .npy magic"},
      {"version", bad_version, "unsupported .npy version 9.0"},
      {"header longer than file", long_header, "header length 32767 exceeds"},
      {"fortran", with("{'descr': '<f4', 'fortran_order': True, 'shape': (2,), }"),
       "np.ascontiguousarray"},
      {"big-endian", with("{'descr': '>f4', 'fortran_order': False, 'shape': (2,), }"),
       "big-endian"},
      {"unsupported dtype", with("{'descr': '<c8', 'fortran_order': False, 'shape': (2,), }"),
       "unsupported dtype '<c8'"},
      {"truncated data", make_npy(ok, data.substr(0, 6)),
       "data holds 6 bytes but '<f4' [2] needs 8"},
      {"trailing data", make_npy(ok, data + "xx"), "(trailing bytes)"},
      {"missing key", with("{'descr': '<f4', 'shape': (2,), }"), "lacks one of"},
      {"unknown key", with("{'descr': '<f4', 'fortran_order': False, 'shape': (2,), 'x': 1}"),
       "unexpected key 'x'"},
      {"duplicate key",
       with("{'descr': '<f4', 'descr': '<f4', 'fortran_order': False, 'shape': (2,)}"),
       "'descr' appears twice"},
      {"bad shape", with("{'descr': '<f4', 'fortran_order': False, 'shape': (2.0,), }"),
       "expected ',' or ')'"},
      {"negative shape", with("{'descr': '<f4', 'fortran_order': False, 'shape': (-2,), }"),
       "integers >= 0"},
      {"overflowing dim",
       with("{'descr': '<f4', 'fortran_order': False, 'shape': (99999999999999999999,), }"),
       "overflows int64"},
      {"overflowing shape",
       with("{'descr': '<f4', 'fortran_order': False, 'shape': (4294967296, 4294967296), }"),
       "more elements than the data can hold"},
      {"unterminated", with("{'descr': '<f4, 'fortran_order': False"), "malformed header"},
      {"not a dict", with("['descr']"), "expected '{'"},
  };
  for (const auto& c : cases) {
    SCOPED_TRACE(c.what);
    const std::string msg = error_of(c.bytes);
    EXPECT_NE(msg.find(c.expect), std::string::npos) << msg;
    EXPECT_NE(msg.find("img.npy"), std::string::npos) << msg;
  }
  // Every prefix of a valid file fails cleanly.
  const auto full = with(ok);
  for (std::size_t len = 0; len < full.size(); ++len) {
    EXPECT_THROW(parse_npy(std::span(full).first(len)), InvalidArgument) << len;
  }
  EXPECT_THROW(read_npy("/nonexistent/vkjr2.npy"), Error);
}

}  // namespace
}  // namespace vkjr2
