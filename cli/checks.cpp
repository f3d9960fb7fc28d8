#include "checks.hpp"

#include <fcntl.h>
#include <unistd.h>

#include <algorithm>
#include <cctype>
#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <limits>
#include <sstream>
#include <string>
#include <system_error>

namespace vkjr2::cli {
namespace fs = std::filesystem;

namespace {

// The whole of `text` as a double (strtod: decimal, exponent, "nan", "inf").
bool parse_double(const std::string& text, double& out) {
  if (text.empty() || std::isspace(static_cast<unsigned char>(text.front()))) return false;
  char* end = nullptr;
  errno = 0;
  out = std::strtod(text.c_str(), &end);
  return end == text.c_str() + text.size();
}

// The whole of `text` as a decimal integer with an optional leading '-'.
bool parse_integer(const std::string& text, std::int64_t& out) {
  if (text.empty()) return false;
  const std::size_t digits_from = text.front() == '-' ? 1 : 0;
  if (digits_from == text.size()) return false;
  if (!std::all_of(text.begin() + std::ptrdiff_t(digits_from), text.end(),
                   [](unsigned char c) { return std::isdigit(c) != 0; }))
    return false;
  char* end = nullptr;
  errno = 0;
  out = std::strtoll(text.c_str(), &end, 10);
  return errno != ERANGE && end == text.c_str() + text.size();
}

std::string in_quotes(const std::string& text) { return "'" + text + "'"; }

}  // namespace

namespace {

bool user_facing(const std::string& op) {
  if (op.empty()) return false;
  if (op.front() == '-') return true;
  return std::all_of(op.begin(), op.end(), [](unsigned char c) {
    return std::isupper(c) != 0 || std::isdigit(c) != 0 || c == '_' || c == '/';
  });
}

}  // namespace

std::string describe_error(const Error& e) {
  std::string text = user_facing(e.op()) ? e.op() + ": " + e.problem() : e.problem();
  if (e.result() != VK_SUCCESS) text += " [" + std::string(vk_result_name(e.result())) + "]";
  if (!e.fix().empty()) text += ". Fix: " + e.fix();
  return text;
}

std::string readable(double v) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%.6g", v);
  return buf;
}

CLI::Validator finite_range(double lo, double hi) {
  const std::string range = readable(lo) + ".." + readable(hi);
  return CLI::Validator(
      [lo, hi, range](std::string& text) -> std::string {
        double v = 0;
        if (!parse_double(text, v)) return in_quotes(text) + " is not a number";
        if (!std::isfinite(v))
          return in_quotes(text) + " is not a finite number (use " + range + ")";
        if (v < lo || v > hi) return text + " is outside " + range;
        return {};
      },
      "in " + range);
}

CLI::Validator positive_up_to(double hi) {
  const std::string range = "(0, " + readable(hi) + "]";
  return CLI::Validator(
      [hi, range](std::string& text) -> std::string {
        double v = 0;
        if (!parse_double(text, v)) return in_quotes(text) + " is not a number";
        if (!std::isfinite(v))
          return in_quotes(text) + " is not a finite number (use " + range + ")";
        if (v <= 0) return text + " is not positive (use " + range + ")";
        if (v > hi) return text + " is above " + readable(hi);
        return {};
      },
      "in " + range);
}

CLI::Validator integer_range(std::int64_t lo, std::int64_t hi) {
  const std::string range = std::to_string(lo) + ".." + std::to_string(hi);
  return CLI::Validator(
      [lo, hi, range](std::string& text) -> std::string {
        std::int64_t v = 0;
        if (!parse_integer(text, v))
          return in_quotes(text) + " is not a whole number (use " + range + ")";
        if (v < lo || v > hi) return text + " is outside " + range;
        return {};
      },
      "in " + range);
}

std::vector<std::string> split_list(const std::string& text) {
  std::vector<std::string> out;
  std::stringstream ss(text);
  std::string item;
  while (std::getline(ss, item, ',')) out.push_back(item);
  return out;
}

std::uint64_t parse_seed(const std::string& text, const std::string& option) {
  const bool digits =
      !text.empty() && text.size() <= 20 &&
      std::all_of(text.begin(), text.end(), [](unsigned char c) { return std::isdigit(c) != 0; });
  if (digits) {
    errno = 0;
    char* end = nullptr;
    const unsigned long long v = std::strtoull(text.c_str(), &end, 10);
    if (errno != ERANGE && end == text.c_str() + text.size()) return v;
  }
  throw UsageError(option, in_quotes(text) + " is not a seed",
                   "use a whole number in 0..18446744073709551615");
}

namespace {

template <typename Seed>
CLI::Option* add_seed(CLI::App* cmd, Seed& seed, const std::string& help, Seed default_seed,
                      const std::string& name) {
  constexpr std::uint64_t kMax = std::numeric_limits<Seed>::max();
  const std::string range = "0.." + std::to_string(kMax);
  seed = default_seed;
  const auto parse = [name, range](const std::string& text) {
    const std::uint64_t v = parse_seed(text, name);
    if (v > kMax) {
      throw UsageError(name, in_quotes(text) + " is not a seed", "give a whole number in " + range);
    }
    return Seed(v);
  };
  return cmd
      ->add_option_function<std::string>(
          name, [&seed, parse](const std::string& text) { seed = parse(text); },
          help + " (a whole number, " + range + "; default " + std::to_string(default_seed) + ")")
      ->check(CLI::Validator(
          [parse](std::string& text) -> std::string {
            try {
              parse(text);
              return {};
            } catch (const UsageError& e) {
              return e.problem() + " (" + e.fix() + ")";
            }
          },
          ""))
      ->type_name("UINT");
}

}  // namespace

CLI::Option* add_seed_option(CLI::App* cmd, std::uint64_t& seed, const std::string& help,
                             std::uint64_t default_seed, const std::string& name) {
  return add_seed(cmd, seed, help, default_seed, name);
}

CLI::Option* add_seed_option(CLI::App* cmd, std::uint32_t& seed, const std::string& help,
                             std::uint32_t default_seed, const std::string& name) {
  return add_seed(cmd, seed, help, default_seed, name);
}

CLI::Validator fft_length(std::int64_t lo, std::int64_t hi) {
  const CLI::Validator in_range = integer_range(lo, hi);
  return CLI::Validator(
      [in_range](std::string& text) -> std::string {
        std::string bad = in_range(text);
        if (!bad.empty()) return bad;
        std::int64_t n = std::stoll(text);
        for (const std::int64_t f : {2, 3, 5, 7})
          while (n % f == 0) n /= f;
        if (n != 1) return text + " is not an FFT length 2^a 3^b 5^c 7^d (e.g. 128, 192, 256)";
        return {};
      },
      "an FFT length 2^a 3^b 5^c 7^d in " + std::to_string(lo) + ".." + std::to_string(hi));
}

CLI::Validator odd_number(std::int64_t lo, std::int64_t hi, bool zero_ok) {
  const CLI::Validator in_range = integer_range(zero_ok ? 0 : lo, hi);
  return CLI::Validator(
      [in_range, lo, zero_ok](std::string& text) -> std::string {
        std::string bad = in_range(text);
        if (!bad.empty()) return bad;
        const std::int64_t n = std::stoll(text);
        if (zero_ok && n == 0) return {};
        if (n < lo) return text + " is below " + std::to_string(lo);
        if (n % 2 == 0) return text + " is even; it must be odd (a kernel has a centre pixel)";
        return {};
      },
      std::string("odd") + (zero_ok ? " or 0" : ""));
}

void check_input_file(const fs::path& path, const std::string& what) {
  std::error_code ec;
  const fs::file_status st = fs::status(path, ec);
  if (ec && ec != std::errc::no_such_file_or_directory) {
    throw Error(what, "cannot reach " + path.string() + ": " + ec.message(),
                "check the path and its folders' permissions");
  }
  if (!fs::exists(st)) throw UsageError(what, path.string() + " does not exist", "check the path");
  if (fs::is_directory(st)) {
    throw UsageError(what, path.string() + " is a folder, not a file", "name a file");
  }
  const int fd = ::open(path.c_str(), O_RDONLY | O_CLOEXEC);
  if (fd < 0) {
    const int err = errno;
    throw Error(what, "cannot read " + path.string() + ": " + std::strerror(err),
                err == EACCES ? "give yourself read permission (chmod u+r) or run as its owner"
                              : "check the file");
  }
  ::close(fd);
}

void check_input_folder(const fs::path& path, const std::string& what) {
  std::error_code ec;
  const fs::file_status st = fs::status(path, ec);
  if (!fs::exists(st)) throw UsageError(what, path.string() + " does not exist", "check the path");
  if (!fs::is_directory(st)) {
    throw UsageError(what, path.string() + " is not a folder", "name a folder");
  }
  if (::access(path.c_str(), R_OK | X_OK) != 0) {
    throw Error(what, "cannot read the folder " + path.string() + ": " + std::strerror(errno),
                "give yourself read permission or run as its owner");
  }
}

namespace {

fs::path folder_of(const fs::path& path) {
  return path.has_parent_path() ? path.parent_path() : fs::path(".");
}

void check_parent_writable(const fs::path& path, const std::string& what) {
  const fs::path dir = folder_of(path);
  std::error_code ec;
  const fs::file_status st = fs::status(dir, ec);
  if (!fs::exists(st)) {
    throw UsageError(what,
                     "the folder " + dir.string() + " of " + path.string() + " does not exist",
                     "create it first (mkdir -p " + dir.string() + ")");
  }
  if (!fs::is_directory(st)) {
    throw UsageError(what, dir.string() + " (in " + path.string() + ") is not a folder",
                     "check the path");
  }
  if (::access(dir.c_str(), W_OK | X_OK) != 0) {
    throw Error(what, "cannot write into " + dir.string() + ": " + std::strerror(errno),
                "pick a folder you can write to");
  }
}

}  // namespace

void check_output_file(const fs::path& path, bool force, const std::string& what) {
  if (path.empty()) throw UsageError(what, "the output path is empty", "name a file");
  std::error_code ec;
  const fs::file_status st = fs::status(path, ec);
  if (fs::is_directory(st)) {
    throw UsageError(what, path.string() + " is a folder, not a file",
                     "name a file (e.g. " + (path / "out").string() + lower_extension(path) + ")");
  }
  if (fs::exists(st) && !fs::is_regular_file(st)) {
    throw UsageError(what, path.string() + " exists and is not a regular file", "name a new file");
  }
  if (fs::exists(st) && !force) {
    throw UsageError(what, path.string() + " already exists", "pass --force to replace it");
  }
  check_parent_writable(path, what);
}

void check_output_folder(const fs::path& path, const std::string& what) {
  if (path.empty()) throw UsageError(what, "the output folder is empty", "name a folder");
  std::error_code ec;
  const fs::file_status st = fs::status(path, ec);
  if (fs::exists(st) && !fs::is_directory(st)) {
    throw UsageError(what, path.string() + " is a file, not a folder",
                     "name a folder (it is created when missing)");
  }
  if (!fs::exists(st)) {
    // Created by the command: its parent must be there.
    fs::path parent = path.lexically_normal();
    if (!parent.has_filename()) parent = parent.parent_path();
    check_parent_writable(parent, what);
  } else if (::access(path.c_str(), W_OK | X_OK) != 0) {
    throw Error(what, "cannot write into " + path.string() + ": " + std::strerror(errno),
                "pick a folder you can write to");
  }
}

std::string lower_extension(const fs::path& path) {
  std::string e = path.extension().string();
  std::transform(e.begin(), e.end(), e.begin(),
                 [](unsigned char c) { return char(std::tolower(c)); });
  return e;
}

bool has_extension(const fs::path& path, std::initializer_list<const char*> extensions) {
  const std::string e = lower_extension(path);
  return std::any_of(extensions.begin(), extensions.end(), [&](const char* k) { return e == k; });
}

void check_extension(const fs::path& path, std::initializer_list<const char*> allowed,
                     const std::string& what) {
  if (has_extension(path, allowed)) return;
  const std::string e = lower_extension(path);
  std::string list;
  for (const char* a : allowed) list += (list.empty() ? "" : ", ") + std::string(a);
  throw UsageError(what,
                   path.string() + ": " +
                       (e.empty() ? std::string("no extension") : "extension '" + e + "'") +
                       " is not a format this writes",
                   "name the file with one of " + list);
}

}  // namespace vkjr2::cli
