#include <vkjr2/nets/safetensors.hpp>

#include <nlohmann/json.hpp>

#include <algorithm>
#include <bit>
#include <cmath>
#include <cstring>
#include <numeric>
#include <set>
#include <utility>

#include "internal/half.hpp"

namespace vkjr2::nets {
namespace {

static_assert(std::endian::native == std::endian::little,
              "safetensors stores little-endian data; add byte swapping for big-endian hosts");

constexpr const char* kReadOp = "read_safetensors";
constexpr const char* kWriteOp = "write_safetensors";
// The reference reader refuses headers above 100 MB; so do we.
constexpr std::uint64_t kMaxHeaderBytes = 100'000'000;

struct DTypeInfo {
  StDType dtype;
  const char* name;
  std::size_t size;
};
constexpr DTypeInfo kDTypes[] = {
    {StDType::BOOL, "BOOL", 1}, {StDType::U8, "U8", 1},   {StDType::I8, "I8", 1},
    {StDType::I16, "I16", 2},   {StDType::U16, "U16", 2}, {StDType::F16, "F16", 2},
    {StDType::BF16, "BF16", 2}, {StDType::I32, "I32", 4}, {StDType::U32, "U32", 4},
    {StDType::F32, "F32", 4},   {StDType::I64, "I64", 8}, {StDType::U64, "U64", 8},
    {StDType::F64, "F64", 8},
};

template <typename T>
T load(const std::byte* p) {
  T v;
  std::memcpy(&v, p, sizeof(T));
  return v;
}

std::string in_quotes(std::string_view s) { return "'" + std::string(s) + "'"; }

[[noreturn]] void bad_file(std::string_view source, const std::string& problem) {
  throw InvalidArgument(kReadOp, in_quotes(source) + ": " + problem,
                        "the file is corrupt, truncated or not a safetensors file; re-create it "
                        "(write_safetensors or Python's safetensors.save_file)");
}

[[noreturn]] void bad_tensor(std::string_view source, std::string_view name,
                             const std::string& problem) {
  bad_file(source, "tensor " + in_quotes(name) + ": " + problem);
}

std::int64_t json_dim(const nlohmann::json& v, std::string_view source, std::string_view name,
                      const char* field) {
  if (!v.is_number_unsigned() || v.get<std::uint64_t>() > std::uint64_t(INT64_MAX)) {
    bad_tensor(source, name,
               std::string(field) + " holds " + v.dump() + ", expected a non-negative integer");
  }
  return std::int64_t(v.get<std::uint64_t>());
}

struct Entry {
  std::string name;
  StDType dtype;
  std::vector<std::int64_t> shape;
  std::uint64_t begin, end;
};

Entry parse_entry(const std::string& name, const nlohmann::json& info, std::string_view source,
                  std::uint64_t buffer_bytes) {
  if (!info.is_object()) bad_tensor(source, name, "entry is " + info.dump() + ", not an object");
  const auto dtype_it = info.find("dtype");
  const auto shape_it = info.find("shape");
  const auto offsets_it = info.find("data_offsets");
  if (dtype_it == info.end() || shape_it == info.end() || offsets_it == info.end()) {
    bad_tensor(source, name, "entry lacks one of \"dtype\", \"shape\", \"data_offsets\"");
  }
  if (!dtype_it->is_string()) bad_tensor(source, name, "\"dtype\" is not a string");
  const auto dtype = st_dtype_from_name(dtype_it->get_ref<const std::string&>());
  if (!dtype) {
    bad_tensor(source, name,
               "unsupported dtype " + dtype_it->dump() +
                   " (supported: BOOL U8 I8 I16 U16 F16 BF16 I32 U32 F32 I64 U64 F64)");
  }
  if (!shape_it->is_array()) bad_tensor(source, name, "\"shape\" is not an array");
  Entry e{name, *dtype, {}, 0, 0};
  e.shape.reserve(std::min<std::size_t>(shape_it->size(), 64));
  for (const auto& d : *shape_it) e.shape.push_back(json_dim(d, source, name, "shape"));
  if (!offsets_it->is_array() || offsets_it->size() != 2) {
    bad_tensor(source, name, "\"data_offsets\" is not an array [begin, end]");
  }
  e.begin = std::uint64_t(json_dim((*offsets_it)[0], source, name, "data_offsets"));
  e.end = std::uint64_t(json_dim((*offsets_it)[1], source, name, "data_offsets"));
  if (e.begin > e.end || e.end > buffer_bytes) {
    bad_tensor(source, name,
               "data_offsets [" + std::to_string(e.begin) + ", " + std::to_string(e.end) +
                   "] lie outside the " + std::to_string(buffer_bytes) + "-byte data buffer");
  }
  // numel can be no larger than the buffer (every element takes >= 1 byte),
  // which also bounds numel * size below 2^63.
  const std::int64_t numel = checked_numel(e.shape, std::string(source) + " tensor '" + name + "'",
                                           std::int64_t(buffer_bytes));
  const std::uint64_t want = std::uint64_t(numel) * st_dtype_size(e.dtype);
  if (e.end - e.begin != want) {
    bad_tensor(source, name,
               "data_offsets [" + std::to_string(e.begin) + ", " + std::to_string(e.end) +
                   "] span " + std::to_string(e.end - e.begin) + " bytes but " +
                   st_dtype_name(e.dtype) + " " + shape_str(e.shape) + " needs " +
                   std::to_string(want));
  }
  return e;
}

void check_names(std::span<const SafetensorsRecord> records) {
  std::set<std::string_view> seen;
  for (const auto& r : records) {
    if (r.name.empty()) {
      throw InvalidArgument(kWriteOp, "a tensor has an empty name", "give every tensor a name");
    }
    if (r.name == "__metadata__") {
      throw InvalidArgument(kWriteOp, "'__metadata__' is reserved for the metadata block",
                            "rename the tensor");
    }
    if (!seen.insert(r.name).second) {
      throw InvalidArgument(kWriteOp, "tensor name " + in_quotes(r.name) + " appears twice",
                            "give every tensor a unique name");
    }
    const std::int64_t numel = checked_numel(r.shape, "tensor '" + r.name + "'");
    std::uint64_t want = 0;
    if (__builtin_mul_overflow(std::uint64_t(numel), st_dtype_size(r.dtype), &want) ||
        want != r.data.size()) {
      throw InvalidArgument(
          kWriteOp,
          "tensor " + in_quotes(r.name) + " holds " + std::to_string(r.data.size()) +
              " bytes but " + st_dtype_name(r.dtype) + " " + shape_str(r.shape) + " needs " +
              std::to_string(numel) + " x " + std::to_string(st_dtype_size(r.dtype)),
          "make data match dtype and shape");
    }
  }
}

template <typename T>
SafetensorsRecord make_record(std::string name, std::vector<std::int64_t> shape, StDType dtype,
                              std::span<const T> values) {
  SafetensorsRecord r;
  r.name = std::move(name);
  r.dtype = dtype;
  r.shape = std::move(shape);
  const std::int64_t numel = checked_numel(r.shape, "tensor '" + r.name + "'");
  if (numel != std::int64_t(values.size())) {
    throw InvalidArgument("SafetensorsRecord",
                          "tensor " + in_quotes(r.name) + " has shape " + shape_str(r.shape) +
                              " (" + std::to_string(numel) + " elements) but " +
                              std::to_string(values.size()) + " values",
                          "pass as many values as the shape holds");
  }
  r.data.resize(values.size_bytes());
  if (!values.empty()) std::memcpy(r.data.data(), values.data(), values.size_bytes());
  return r;
}

template <typename T>
std::vector<T> raw_as(const SafetensorsRecord& r, StDType want) {
  if (r.dtype != want) {
    throw InvalidArgument("SafetensorsRecord",
                          "tensor " + in_quotes(r.name) + " is " + st_dtype_name(r.dtype) +
                              ", not " + st_dtype_name(want),
                          "read it with to_float() or store it with the expected dtype");
  }
  std::vector<T> out(r.data.size() / sizeof(T));
  if (!out.empty()) std::memcpy(out.data(), r.data.data(), out.size() * sizeof(T));
  return out;
}

}  // namespace

std::size_t st_dtype_size(StDType dtype) noexcept {
  for (const auto& d : kDTypes) {
    if (d.dtype == dtype) return d.size;
  }
  return 0;
}

const char* st_dtype_name(StDType dtype) noexcept {
  for (const auto& d : kDTypes) {
    if (d.dtype == dtype) return d.name;
  }
  return "?";
}

std::optional<StDType> st_dtype_from_name(std::string_view name) noexcept {
  for (const auto& d : kDTypes) {
    if (name == d.name) return d.dtype;
  }
  return std::nullopt;
}

std::int64_t SafetensorsRecord::numel() const {
  return checked_numel(shape, "tensor '" + name + "'");
}

std::vector<float> SafetensorsRecord::to_float() const {
  const std::size_t size = st_dtype_size(dtype);
  const std::size_t n = size ? data.size() / size : 0;
  if (std::int64_t(n) != numel() || n * size != data.size()) {
    throw InvalidArgument("SafetensorsRecord::to_float",
                          "tensor " + in_quotes(name) + " holds " + std::to_string(data.size()) +
                              " bytes, not " + st_dtype_name(dtype) + " " + shape_str(shape),
                          "make data match dtype and shape");
  }
  std::vector<float> out(n);
  const std::byte* p = data.data();
  for (std::size_t i = 0; i < n; ++i, p += size) {
    switch (dtype) {
      case StDType::BOOL:
        out[i] = load<std::uint8_t>(p) ? 1.f : 0.f;
        break;
      case StDType::U8:
        out[i] = float(load<std::uint8_t>(p));
        break;
      case StDType::I8:
        out[i] = float(load<std::int8_t>(p));
        break;
      case StDType::I16:
        out[i] = float(load<std::int16_t>(p));
        break;
      case StDType::U16:
        out[i] = float(load<std::uint16_t>(p));
        break;
      case StDType::F16:
        out[i] = detail::half_to_float(load<std::uint16_t>(p));
        break;
      case StDType::BF16:
        out[i] = std::bit_cast<float>(std::uint32_t(load<std::uint16_t>(p)) << 16);
        break;
      case StDType::I32:
        out[i] = float(load<std::int32_t>(p));
        break;
      case StDType::U32:
        out[i] = float(load<std::uint32_t>(p));
        break;
      case StDType::F32:
        out[i] = load<float>(p);
        break;
      case StDType::I64:
        out[i] = float(load<std::int64_t>(p));
        break;
      case StDType::U64:
        out[i] = float(load<std::uint64_t>(p));
        break;
      case StDType::F64:
        out[i] = float(load<double>(p));
        break;
    }
  }
  return out;
}

HostTensor SafetensorsRecord::to_host() const { return HostTensor{shape, to_float()}; }

std::vector<std::int32_t> SafetensorsRecord::as_i32() const {
  return raw_as<std::int32_t>(*this, StDType::I32);
}

std::vector<std::uint32_t> SafetensorsRecord::as_u32() const {
  return raw_as<std::uint32_t>(*this, StDType::U32);
}

SafetensorsRecord SafetensorsRecord::f32(std::string name, std::vector<std::int64_t> shape,
                                         std::span<const float> values) {
  return make_record(std::move(name), std::move(shape), StDType::F32, values);
}

SafetensorsRecord SafetensorsRecord::i32(std::string name, std::vector<std::int64_t> shape,
                                         std::span<const std::int32_t> values) {
  return make_record(std::move(name), std::move(shape), StDType::I32, values);
}

SafetensorsRecord SafetensorsRecord::u32(std::string name, std::vector<std::int64_t> shape,
                                         std::span<const std::uint32_t> values) {
  return make_record(std::move(name), std::move(shape), StDType::U32, values);
}

const SafetensorsRecord* SafetensorsFile::find(std::string_view name) const noexcept {
  for (const auto& t : tensors) {
    if (t.name == name) return &t;
  }
  return nullptr;
}

const SafetensorsRecord& SafetensorsFile::at(std::string_view name) const {
  if (const auto* t = find(name)) return *t;
  std::string present;
  for (std::size_t i = 0; i < tensors.size() && i < 20; ++i) {
    present += (i ? ", " : "") + in_quotes(tensors[i].name);
  }
  if (tensors.size() > 20) present += ", ... (" + std::to_string(tensors.size()) + " in all)";
  throw InvalidArgument("SafetensorsFile::at",
                        "no tensor named " + in_quotes(name) +
                            "; present: " + (present.empty() ? std::string("none") : present),
                        "check the name or the file it was read from");
}

SafetensorsFile parse_safetensors(std::span<const std::byte> bytes, std::string_view source) {
  if (bytes.size() < 8) {
    bad_file(source, "only " + std::to_string(bytes.size()) +
                         " bytes, shorter than the 8-byte header length");
  }
  const std::uint64_t header_bytes = load<std::uint64_t>(bytes.data());
  if (header_bytes > bytes.size() - 8) {
    bad_file(source, "header length " + std::to_string(header_bytes) + " exceeds the " +
                         std::to_string(bytes.size() - 8) + " bytes that follow it");
  }
  if (header_bytes > kMaxHeaderBytes) {
    bad_file(source, "header length " + std::to_string(header_bytes) + " exceeds the 100 MB limit");
  }
  const auto* header_begin = reinterpret_cast<const char*>(bytes.data() + 8);
  if (header_bytes == 0 || header_begin[0] != '{') {
    bad_file(source, "header does not start with '{'");
  }
  // Duplicate keys: nlohmann keeps the last silently, so watch keys as parsed.
  std::vector<std::set<std::string>> open_objects;
  std::string duplicate;
  const auto watch = [&](int, nlohmann::json::parse_event_t event, nlohmann::json& parsed) {
    using E = nlohmann::json::parse_event_t;
    if (event == E::object_start) {
      open_objects.emplace_back();
    } else if (event == E::object_end) {
      if (!open_objects.empty()) open_objects.pop_back();
    } else if (event == E::key && !open_objects.empty() && parsed.is_string()) {
      if (!open_objects.back().insert(parsed.get<std::string>()).second && duplicate.empty()) {
        duplicate = parsed.get<std::string>();
      }
    }
    return true;
  };
  nlohmann::json header;
  try {
    header = nlohmann::json::parse(header_begin, header_begin + header_bytes, watch);
  } catch (const nlohmann::json::exception& e) {
    bad_file(source, std::string("header is not valid JSON: ") + e.what());
  }
  if (!duplicate.empty()) bad_file(source, "header names " + in_quotes(duplicate) + " twice");
  if (!header.is_object()) bad_file(source, "header is not a JSON object");

  const std::span<const std::byte> buffer = bytes.subspan(8 + header_bytes);
  SafetensorsFile file;
  std::vector<Entry> entries;
  for (const auto& [key, value] : header.items()) {
    if (key == "__metadata__") {
      if (!value.is_object()) bad_file(source, "\"__metadata__\" is not an object");
      for (const auto& [mk, mv] : value.items()) {
        if (!mv.is_string()) {
          bad_file(source, "metadata " + in_quotes(mk) + " is " + mv.dump() + ", not a string");
        }
        file.metadata.emplace(mk, mv.get<std::string>());
      }
      continue;
    }
    entries.push_back(parse_entry(key, value, source, buffer.size()));
  }
  // The tensors must tile the buffer exactly (the reference reader's rule).
  std::sort(entries.begin(), entries.end(), [](const Entry& a, const Entry& b) {
    return std::tie(a.begin, a.end) < std::tie(b.begin, b.end);
  });
  std::uint64_t expected = 0;
  const Entry* previous = nullptr;
  for (const auto& e : entries) {
    if (e.begin < expected) {
      bad_tensor(source, e.name,
                 "data_offsets [" + std::to_string(e.begin) + ", " + std::to_string(e.end) +
                     "] overlap tensor " + in_quotes(previous->name) + " (ends at " +
                     std::to_string(expected) + ")");
    }
    if (e.begin > expected) {
      bad_tensor(source, e.name,
                 "data starts at byte " + std::to_string(e.begin) +
                     " but the previous tensor ends at " + std::to_string(expected) +
                     " (the buffer must have no holes)");
    }
    expected = e.end;
    previous = &e;
  }
  if (expected != buffer.size()) {
    bad_file(source, "the tensors cover " + std::to_string(expected) + " of the " +
                         std::to_string(buffer.size()) + " data bytes (" +
                         std::to_string(buffer.size() - expected) + " trailing bytes)");
  }
  file.tensors.reserve(entries.size());
  for (auto& e : entries) {
    SafetensorsRecord r;
    r.name = std::move(e.name);
    r.dtype = e.dtype;
    r.shape = std::move(e.shape);
    r.data.assign(buffer.begin() + std::ptrdiff_t(e.begin), buffer.begin() + std::ptrdiff_t(e.end));
    file.tensors.push_back(std::move(r));
  }
  return file;
}

SafetensorsFile read_safetensors(const std::filesystem::path& path) {
  const std::vector<std::byte> bytes = read_file_bytes(path, kReadOp);
  return parse_safetensors(bytes, path.string());
}

std::vector<std::byte> serialize_safetensors(std::span<const SafetensorsRecord> records,
                                             const std::map<std::string, std::string>& metadata) {
  check_names(records);
  std::vector<std::size_t> order(records.size());
  std::iota(order.begin(), order.end(), std::size_t{0});
  std::sort(order.begin(), order.end(), [&](std::size_t a, std::size_t b) {
    const std::size_t sa = st_dtype_size(records[a].dtype);
    const std::size_t sb = st_dtype_size(records[b].dtype);
    return sa != sb ? sa > sb : records[a].name < records[b].name;
  });
  nlohmann::json header = nlohmann::json::object();
  if (!metadata.empty()) header["__metadata__"] = metadata;
  std::uint64_t offset = 0;
  for (std::size_t i : order) {
    const auto& r = records[i];
    header[r.name] = {{"dtype", st_dtype_name(r.dtype)},
                      {"shape", r.shape},
                      {"data_offsets", {offset, offset + r.data.size()}}};
    offset += r.data.size();
  }
  std::string text;
  try {
    text = header.dump();
  } catch (const nlohmann::json::exception& e) {
    throw InvalidArgument(kWriteOp,
                          std::string("a name or metadata string is not UTF-8: ") + e.what(),
                          "use UTF-8 names and metadata");
  }
  text.append((8 - text.size() % 8) % 8, ' ');
  std::vector<std::byte> out(8 + text.size() + offset);
  const std::uint64_t n = text.size();
  std::memcpy(out.data(), &n, 8);
  std::memcpy(out.data() + 8, text.data(), text.size());
  std::byte* p = out.data() + 8 + text.size();
  for (std::size_t i : order) {
    const auto& d = records[i].data;
    if (!d.empty()) std::memcpy(p, d.data(), d.size());
    p += d.size();
  }
  return out;
}

void write_safetensors(const std::filesystem::path& path,
                       std::span<const SafetensorsRecord> records,
                       const std::map<std::string, std::string>& metadata) {
  const std::vector<std::byte> bytes = serialize_safetensors(records, metadata);
  write_file_atomic(path, bytes, kWriteOp);
}

std::map<std::string, HostTensor> read_safetensors_f32(const std::filesystem::path& path) {
  SafetensorsFile file = read_safetensors(path);
  std::map<std::string, HostTensor> out;
  for (const auto& t : file.tensors) out.emplace(t.name, t.to_host());
  return out;
}

void write_safetensors_f32(const std::filesystem::path& path,
                           const std::map<std::string, HostTensor>& tensors,
                           const std::map<std::string, std::string>& metadata) {
  std::vector<SafetensorsRecord> records;
  records.reserve(tensors.size());
  for (const auto& [name, t] : tensors) {
    records.push_back(SafetensorsRecord::f32(name, t.shape, t.values));
  }
  write_safetensors(path, records, metadata);
}

}  // namespace vkjr2::nets
