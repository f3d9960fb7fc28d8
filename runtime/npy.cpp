#include <vkjr2/runtime/npy.hpp>

#include <bit>
#include <cstring>
#include <string>

namespace vkjr2 {
namespace {

static_assert(
    std::endian::native == std::endian::little,
    "the .npy reader converts little-endian data; add byte swapping for big-endian hosts");

constexpr const char* kReadOp = "read_npy";
constexpr const char* kWriteOp = "write_npy";
constexpr char kMagic[] = "\x93NUMPY";
constexpr std::size_t kMagicSize = 6;

std::string in_quotes(std::string_view s) { return "'" + std::string(s) + "'"; }

[[noreturn]] void bad_npy(
    std::string_view source, const std::string& problem,
    const std::string& fix = "the file is corrupt or not a .npy array; re-create it with np.save") {
  throw InvalidArgument(kReadOp, in_quotes(source) + ": " + problem, fix);
}

enum class Kind : std::uint8_t { f4, f8, u1, i4 };

// A recursive-descent reader for the one dict literal numpy writes.
class HeaderParser {
 public:
  HeaderParser(std::string_view text, std::string_view source) : s_(text), source_(source) {}

  void parse(std::string& descr, bool& fortran, std::vector<std::int64_t>& shape) {
    bool have_descr = false, have_fortran = false, have_shape = false;
    skip_ws();
    expect('{');
    while (true) {
      skip_ws();
      if (peek() == '}') {
        ++pos_;
        break;
      }
      const std::string key = string_literal();
      skip_ws();
      expect(':');
      skip_ws();
      if (key == "descr") {
        if (have_descr) fail("key 'descr' appears twice");
        descr = string_literal();
        have_descr = true;
      } else if (key == "fortran_order") {
        if (have_fortran) fail("key 'fortran_order' appears twice");
        fortran = boolean();
        have_fortran = true;
      } else if (key == "shape") {
        if (have_shape) fail("key 'shape' appears twice");
        shape = tuple();
        have_shape = true;
      } else {
        fail("unexpected key " + in_quotes(key) + " (expected 'descr', 'fortran_order', 'shape')");
      }
      skip_ws();
      if (peek() == ',') {
        ++pos_;
      } else if (peek() != '}') {
        fail("expected ',' or '}' at header byte " + std::to_string(pos_));
      }
    }
    skip_ws();
    if (pos_ != s_.size()) fail("unexpected text after the header dict");
    if (!have_descr || !have_fortran || !have_shape) {
      fail("header dict lacks one of 'descr', 'fortran_order', 'shape'");
    }
  }

 private:
  [[noreturn]] void fail(const std::string& problem) {
    bad_npy(source_, "malformed header: " + problem);
  }
  char peek() const { return pos_ < s_.size() ? s_[pos_] : '\0'; }
  void skip_ws() {
    while (pos_ < s_.size() && (s_[pos_] == ' ' || s_[pos_] == '\n' || s_[pos_] == '\t' ||
                                s_[pos_] == '\r' || s_[pos_] == '\0')) {
      ++pos_;
    }
  }
  void expect(char c) {
    if (peek() != c)
      fail(std::string("expected '") + c + "' at header byte " + std::to_string(pos_));
    ++pos_;
  }
  std::string string_literal() {
    const char q = peek();
    if (q != '\'' && q != '"')
      fail("expected a quoted string at header byte " + std::to_string(pos_));
    ++pos_;
    const std::size_t end = s_.find(q, pos_);
    if (end == std::string_view::npos) fail("unterminated string");
    std::string out(s_.substr(pos_, end - pos_));
    if (out.find('\\') != std::string::npos) fail("escape sequences are not supported in strings");
    pos_ = end + 1;
    return out;
  }
  bool boolean() {
    if (s_.substr(pos_, 4) == "True") {
      pos_ += 4;
      return true;
    }
    if (s_.substr(pos_, 5) == "False") {
      pos_ += 5;
      return false;
    }
    fail("'fortran_order' is not True or False");
  }
  std::vector<std::int64_t> tuple() {
    expect('(');
    std::vector<std::int64_t> dims;
    while (true) {
      skip_ws();
      if (peek() == ')') {
        ++pos_;
        return dims;
      }
      if (peek() < '0' || peek() > '9') fail("'shape' holds something other than integers >= 0");
      std::int64_t v = 0;
      while (peek() >= '0' && peek() <= '9') {
        if (__builtin_mul_overflow(v, 10, &v) || __builtin_add_overflow(v, peek() - '0', &v)) {
          fail("a 'shape' dimension overflows int64");
        }
        ++pos_;
      }
      if (peek() == 'L') ++pos_;  // Python 2 longs, written by old numpy
      dims.push_back(v);
      skip_ws();
      if (peek() == ',') {
        ++pos_;
      } else if (peek() != ')') {
        fail("expected ',' or ')' in 'shape'");
      }
    }
  }

  std::string_view s_;
  std::string_view source_;
  std::size_t pos_ = 0;
};

Kind parse_descr(std::string_view source, const std::string& descr) {
  if (descr == "<f4") return Kind::f4;
  if (descr == "<f8") return Kind::f8;
  if (descr == "|u1" || descr == "<u1") return Kind::u1;
  if (descr == "<i4") return Kind::i4;
  if (!descr.empty() && descr[0] == '>') {
    bad_npy(source, "dtype " + in_quotes(descr) + " is big-endian",
            "save a little-endian array: np.save(path, a.astype(a.dtype.newbyteorder('<')))");
  }
  bad_npy(source,
          "unsupported dtype " + in_quotes(descr) + " (supported: '<f4', '<f8', '|u1', '<i4')",
          "convert before saving, e.g. np.save(path, a.astype(np.float32))");
}

std::size_t item_size(Kind k) {
  switch (k) {
    case Kind::u1:
      return 1;
    case Kind::f4:
    case Kind::i4:
      return 4;
    case Kind::f8:
      return 8;
  }
  return 0;
}

}  // namespace

HostTensor parse_npy(std::span<const std::byte> bytes, std::string_view source) {
  if (bytes.size() < 10 || std::memcmp(bytes.data(), kMagic, kMagicSize) != 0) {
    bad_npy(source, "does not start with the .npy magic \"\\x93NUMPY\"");
  }
  const auto major = std::uint8_t(bytes[6]);
  const auto minor = std::uint8_t(bytes[7]);
  if (major < 1 || major > 3 || minor != 0) {
    bad_npy(source, "unsupported .npy version " + std::to_string(major) + "." +
                        std::to_string(minor) + " (supported: 1.0, 2.0, 3.0)");
  }
  std::size_t prefix = 10;
  std::uint64_t header_len = 0;
  if (major == 1) {
    header_len =
        std::uint64_t(std::uint8_t(bytes[8])) | (std::uint64_t(std::uint8_t(bytes[9])) << 8);
  } else {
    if (bytes.size() < 12) bad_npy(source, "file ends inside the header length");
    prefix = 12;
    for (int i = 0; i < 4; ++i) header_len |= std::uint64_t(std::uint8_t(bytes[8 + i])) << (8 * i);
  }
  if (header_len > bytes.size() - prefix) {
    bad_npy(source, "header length " + std::to_string(header_len) + " exceeds the " +
                        std::to_string(bytes.size() - prefix) + " bytes that follow it");
  }
  const std::string_view header(reinterpret_cast<const char*>(bytes.data() + prefix),
                                std::size_t(header_len));
  std::string descr;
  bool fortran = false;
  std::vector<std::int64_t> shape;
  HeaderParser(header, source).parse(descr, fortran, shape);
  const Kind kind = parse_descr(source, descr);
  if (fortran) {
    bad_npy(source, "array is in Fortran (column-major) order",
            "save a C-order array: np.save(path, np.ascontiguousarray(a))");
  }
  const std::span<const std::byte> data = bytes.subspan(prefix + std::size_t(header_len));
  const std::int64_t numel = checked_numel(shape, std::string(source) + " .npy", INT64_MAX / 8);
  const std::uint64_t want = std::uint64_t(numel) * item_size(kind);
  if (want != data.size()) {
    bad_npy(source, "data holds " + std::to_string(data.size()) + " bytes but " + in_quotes(descr) +
                        " " + shape_str(shape) + " needs " + std::to_string(want) +
                        (want > data.size() ? " (truncated)" : " (trailing bytes)"));
  }
  HostTensor t;
  t.shape = std::move(shape);
  t.values.resize(std::size_t(numel));
  const std::byte* p = data.data();
  for (std::size_t i = 0; i < t.values.size(); ++i) {
    switch (kind) {
      case Kind::f4:
        std::memcpy(&t.values[i], p + 4 * i, 4);
        break;
      case Kind::f8: {
        double v;
        std::memcpy(&v, p + 8 * i, 8);
        t.values[i] = float(v);
        break;
      }
      case Kind::u1:
        t.values[i] = float(std::uint8_t(p[i]));
        break;
      case Kind::i4: {
        std::int32_t v;
        std::memcpy(&v, p + 4 * i, 4);
        t.values[i] = float(v);
        break;
      }
    }
  }
  return t;
}

HostTensor read_npy(const std::filesystem::path& path) {
  const std::vector<std::byte> bytes = read_file_bytes(path, kReadOp);
  return parse_npy(bytes, path.string());
}

std::vector<std::byte> serialize_npy(const HostTensor& tensor) {
  const std::int64_t numel = checked_numel(tensor.shape, "write_npy tensor");
  if (numel != std::int64_t(tensor.values.size())) {
    throw InvalidArgument(kWriteOp,
                          "tensor of shape " + shape_str(tensor.shape) + " needs " +
                              std::to_string(numel) + " values but holds " +
                              std::to_string(tensor.values.size()),
                          "make values.size() equal the product of shape");
  }
  std::string dict = "{'descr': '<f4', 'fortran_order': False, 'shape': (";
  for (std::size_t i = 0; i < tensor.shape.size(); ++i) {
    dict += (i ? ", " : "") + std::to_string(tensor.shape[i]);
  }
  if (tensor.shape.size() == 1) dict += ",";
  dict += "), }";
  // Prefix + dict + padding + '\n' is a multiple of 64 (numpy's alignment).
  std::size_t prefix = 10;
  std::size_t total = (prefix + dict.size() + 1 + 63) / 64 * 64;
  if (total - prefix > 0xffff) {
    prefix = 12;
    total = (prefix + dict.size() + 1 + 63) / 64 * 64;
  }
  const std::size_t header_len = total - prefix;
  dict.append(header_len - dict.size() - 1, ' ');
  dict += '\n';
  std::vector<std::byte> out(total + tensor.values.size() * sizeof(float));
  std::memcpy(out.data(), kMagic, kMagicSize);
  out[6] = std::byte(prefix == 10 ? 1 : 2);
  out[7] = std::byte(0);
  for (std::size_t i = 0; i < prefix - 8; ++i)
    out[8 + i] = std::byte((header_len >> (8 * i)) & 0xff);
  std::memcpy(out.data() + prefix, dict.data(), dict.size());
  if (!tensor.values.empty()) {
    std::memcpy(out.data() + total, tensor.values.data(), tensor.values.size() * sizeof(float));
  }
  return out;
}

void write_npy(const std::filesystem::path& path, const HostTensor& tensor) {
  const std::vector<std::byte> bytes = serialize_npy(tensor);
  write_file_atomic(path, bytes, kWriteOp);
}

}  // namespace vkjr2
