// Command-line checks every command shares, made before any work:
//   - UsageError: a mistake on the command line (exit code 2), as opposed to
//     a failure during the work (bad file content, device error: exit code 1);
//   - CLI11 validators for numbers (NaN and infinity rejected, ranges printed
//     as a person writes them) and seeds (a non-negative integer that fits);
//   - input and output paths: the input exists and is readable, the output's
//     folder exists, the output is not a folder and is not replaced without
//     --force, its extension names a format we write.
#pragma once

#include <vkjr2/runtime/error.hpp>

#include <CLI/CLI.hpp>

#include <cstdint>
#include <filesystem>
#include <initializer_list>
#include <string>
#include <utility>
#include <vector>

namespace vkjr2::cli {

// A mistake on the command line: main prints it and exits with code 2.
class UsageError : public Error {
 public:
  UsageError(std::string op, std::string problem, std::string fix = {})
      : Error(std::move(op), std::move(problem), std::move(fix)) {}
};

// An error as the user reads it: the problem and the fix, with the op only
// when it is something the user typed (an option "--seed", a positional "IN"),
// never a library function's name ("sim::Params", "read_image").
std::string describe_error(const Error& e);

// A number as a person writes it: "0.5", "1e+12", "2.99", "-3".
std::string readable(double v);

// [lo, hi], finite: "nan", "inf" and values outside are refused.
CLI::Validator finite_range(double lo, double hi);
// (0, hi], finite.
CLI::Validator positive_up_to(double hi);
// An integer in [lo, hi] written in decimal digits (no sign games, no exponent).
CLI::Validator integer_range(std::int64_t lo, std::int64_t hi);

// --seed (or `name`): a non-negative decimal integer below 2^64 (below 2^32
// for a 32-bit seed).
CLI::Option* add_seed_option(CLI::App* cmd, std::uint64_t& seed, const std::string& help,
                             std::uint64_t default_seed = 1, const std::string& name = "--seed");
CLI::Option* add_seed_option(CLI::App* cmd, std::uint32_t& seed, const std::string& help,
                             std::uint32_t default_seed = 1, const std::string& name = "--seed");
// An FFT length 2^a 3^b 5^c 7^d in [lo, hi].
CLI::Validator fft_length(std::int64_t lo, std::int64_t hi);
// An odd whole number in [lo, hi] (or 0 when `zero_ok`).
CLI::Validator odd_number(std::int64_t lo, std::int64_t hi, bool zero_ok = false);
// Parses a seed as --seed does; throws UsageError naming `option` otherwise.
std::uint64_t parse_seed(const std::string& text, const std::string& option);

// An input file named on the command line: it exists (else UsageError) and
// is readable (else Error: permission denied). `what` names it ("IN", "--gallery").
void check_input_file(const std::filesystem::path& path, const std::string& what);
// The same for a folder.
void check_input_folder(const std::filesystem::path& path, const std::string& what);

// An output file: its folder exists and is writable, it is not a folder, and
// it does not exist unless `force`. Throws UsageError (exit 2) otherwise.
void check_output_file(const std::filesystem::path& path, bool force, const std::string& what);
// An output folder: it is not a file, its parent exists. (Created later.)
void check_output_folder(const std::filesystem::path& path, const std::string& what);

// The lowercase extension with its dot (".png").
std::string lower_extension(const std::filesystem::path& path);
// Whether the extension (any case) is one of `extensions` (".png", ".jpg").
bool has_extension(const std::filesystem::path& path,
                   std::initializer_list<const char*> extensions);
// The items of a comma-separated option value ("a,b,,c" → a, b, "", c).
std::vector<std::string> split_list(const std::string& text);

// Throws UsageError unless the extension is one of `allowed` (".png", ".jpg").
void check_extension(const std::filesystem::path& path, std::initializer_list<const char*> allowed,
                     const std::string& what);

}  // namespace vkjr2::cli
