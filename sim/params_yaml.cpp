// YAML configs: the YAML document is turned into the JSON value it denotes
// and read by params_from_json, so keys, semantics and errors are the JSON
// config's (docs/sim.md §1). Plain scalars are typed by the YAML 1.2 core
// schema (null, true/false, integers, floats incl. .inf/.nan); quoted
// scalars are strings.
#include <vkjr2/runtime/error.hpp>
#include <vkjr2/sim/params.hpp>

#include <nlohmann/json.hpp>
#include <yaml-cpp/yaml.h>

#include <cctype>
#include <charconv>
#include <cmath>
#include <initializer_list>
#include <limits>
#include <string>

namespace vkjr2::sim {
namespace {

using json = nlohmann::json;
constexpr const char* kOp = "sim::params_from_yaml";

bool whole(const std::string& s, const char* end, std::errc ec) {
  return ec == std::errc() && end == s.data() + s.size();
}

// A plain scalar's value under the core schema (YAML 1.2.2, §10.3.2).
json plain_scalar(const std::string& s) {
  if (s.empty() || s == "~" || s == "null" || s == "Null" || s == "NULL") return nullptr;
  if (s == "true" || s == "True" || s == "TRUE") return true;
  if (s == "false" || s == "False" || s == "FALSE") return false;
  const std::string digits = s[0] == '+' ? s.substr(1) : s;
  if (!digits.empty() && (std::isdigit(static_cast<unsigned char>(digits[0])) != 0 ||
                          digits[0] == '-' || digits[0] == '.')) {
    long long i = 0;
    const auto [iend, iec] = std::from_chars(digits.data(), digits.data() + digits.size(), i);
    if (whole(digits, iend, iec)) return i;
    double d = 0;
    const auto [dend, dec] = std::from_chars(digits.data(), digits.data() + digits.size(), d);
    if (whole(digits, dend, dec) && std::isfinite(d)) return d;
  }
  for (const char* inf : {".inf", ".Inf", ".INF"}) {
    if (s == inf || s == std::string("+") + inf) return std::numeric_limits<double>::infinity();
    if (s == std::string("-") + inf) return -std::numeric_limits<double>::infinity();
  }
  if (s == ".nan" || s == ".NaN" || s == ".NAN") return std::numeric_limits<double>::quiet_NaN();
  return s;
}

json to_json(const YAML::Node& node, const std::string& where, const std::string& source) {
  switch (node.Type()) {
    case YAML::NodeType::Null:
    case YAML::NodeType::Undefined:
      return nullptr;
    case YAML::NodeType::Scalar:
      // Quoted (and explicitly !!str-tagged) scalars carry the tag "!".
      return node.Tag() == "!" || node.Tag() == "tag:yaml.org,2002:str"
                 ? json(node.Scalar())
                 : plain_scalar(node.Scalar());
    case YAML::NodeType::Sequence: {
      json out = json::array();
      for (std::size_t i = 0; i < node.size(); ++i) {
        out.push_back(to_json(node[i], where + "[" + std::to_string(i) + "]", source));
      }
      return out;
    }
    case YAML::NodeType::Map: {
      json out = json::object();
      for (const auto& item : node) {
        if (!item.first.IsScalar()) {
          throw InvalidArgument(kOp,
                                source + ": a key under " +
                                    (where.empty() ? "the top level" : where) +
                                    " is not a plain name",
                                "write keys as names, e.g. aperture_m: 0.2");
        }
        const std::string key = item.first.Scalar();
        std::string path = where;
        if (!path.empty()) path += '.';
        path += key;
        if (out.contains(key)) {
          std::string problem = source;
          problem.append(": ").append(path).append(" is given twice");
          throw InvalidArgument(kOp, problem, "keep one of them");
        }
        out[key] = to_json(item.second, path, source);
      }
      return out;
    }
  }
  return nullptr;
}

// Block style; JSON scalars are valid YAML scalars (strings double-quoted
// with JSON escapes, numbers in shortest round-trip form); arrays in flow style.
void emit(std::string& out, const json& value, int indent) {
  for (const auto& item : value.items()) {
    out.append(std::size_t(indent), ' ');
    out += item.key() + ":";
    if (item.value().is_object()) {
      out += "\n";
      emit(out, item.value(), indent + 2);
    } else {
      out += " " + item.value().dump() + "\n";
    }
  }
}

}  // namespace

Params params_from_yaml(std::string_view text, std::string_view source) {
  const std::string name(source);
  YAML::Node doc;
  try {
    doc = YAML::Load(std::string(text));
  } catch (const YAML::Exception& e) {
    throw InvalidArgument(kOp,
                          name + " is not valid YAML: line " + std::to_string(e.mark.line + 1) +
                              ", column " + std::to_string(e.mark.column + 1) + ": " + e.msg,
                          "fix the syntax (indentation, a missing ':' or quote, a tab, …)");
  }
  return params_from_json(to_json(doc, "", name).dump(), source);
}

std::string params_to_yaml(const Params& params) {
  const json doc = json::parse(params_to_json(params));
  std::string out = "# vkjr2 simulator parameters (docs/sim.md §1)\n";
  emit(out, doc, 0);
  return out;
}

}  // namespace vkjr2::sim
