#include "sysid/io/yaml_reader.h"

#include <algorithm>
#include <cctype>
#include <cerrno>
#include <cmath>
#include <cstdlib>
#include <limits>
#include <sstream>
#include <utility>

#include "core/text.h"

namespace mjsysid::io {

namespace fs = std::filesystem;

std::string FormatNumber(double x) {
  if (std::isinf(x)) return x > 0 ? ".inf" : "-.inf";
  std::ostringstream out;
  out.precision(10);
  out << x;
  return out.str();
}

namespace {

constexpr double kInf = std::numeric_limits<double>::infinity();

// ---------------------------------------------------------------------------------------------
// scalar conversion (YAML 1.2 core schema numbers; quoted scalars are strings)

std::optional<double> ToDouble(const std::string& s) {
  std::string lower = s;
  for (char& c : lower) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  if (lower == ".inf" || lower == "+.inf") return kInf;
  if (lower == "-.inf") return -kInf;
  if (lower == ".nan") return std::numeric_limits<double>::quiet_NaN();
  if (s.empty() || s.find_first_not_of("0123456789+-.eE") != std::string::npos) return std::nullopt;
  if (s.find_first_of("0123456789") == std::string::npos) return std::nullopt;
  char* end = nullptr;
  errno = 0;
  const double value = std::strtod(s.c_str(), &end);
  if (end != s.c_str() + s.size() || errno == ERANGE) return std::nullopt;
  return value;
}

std::optional<long long> ToInteger(const std::string& s) {
  if (s.empty() || s.find_first_not_of("0123456789+-") != std::string::npos) return std::nullopt;
  char* end = nullptr;
  errno = 0;
  const long long value = std::strtoll(s.c_str(), &end, 10);
  if (end != s.c_str() + s.size() || errno == ERANGE) return std::nullopt;
  return value;
}

// quoted ('x', "x") or explicitly tagged !!str scalars are strings, never numbers or booleans
bool IsQuoted(const YAML::Node& n) { return n.Tag() == "!" || n.Tag() == "tag:yaml.org,2002:str"; }

}  // namespace

std::string Describe(const YAML::Node& n) {
  switch (n.Type()) {
    case YAML::NodeType::Map:
      return "a map";
    case YAML::NodeType::Sequence:
      return "a list";
    case YAML::NodeType::Scalar:
      if (IsQuoted(n)) return "the quoted string \"" + n.Scalar() + "\"";
      if (ToDouble(n.Scalar())) return "the number " + n.Scalar();
      return "the string " + Quote(n.Scalar());
    case YAML::NodeType::Null:
    case YAML::NodeType::Undefined:
      break;
  }
  return "an empty value";
}

// ---------------------------------------------------------------------------------------------
// maps and typed values

MapReader::MapReader(const YamlReader& reader, const Field& field, std::vector<std::string> keys)
    : reader_(reader), field_(field), keys_(std::move(keys)) {
  const std::string where = field_.path.empty() ? "the experiment" : field_.path;
  if (!field_.node.IsMap()) {
    reader_.Fail(field_.mark, where + ": expected a map, got " + Describe(field_.node),
                 "valid keys: " + JoinNames(keys_));
  }
  for (auto it = field_.node.begin(); it != field_.node.end(); ++it) {
    const Mark key_mark = reader_.At(it->first, field_.mark);
    if (!it->first.IsScalar()) {
      reader_.Fail(key_mark, where + ": keys must be plain names, got " + Describe(it->first),
                   "valid keys: " + JoinNames(keys_));
    }
    const std::string key = it->first.Scalar();
    if (std::find(keys_.begin(), keys_.end(), key) == keys_.end()) {
      reader_.Fail(key_mark, "unknown key " + Quote(key) + " in " + where,
                   NamesHint(key, keys_, "keys of " + where));
    }
    if (const auto seen = entries_.find(key); seen != entries_.end()) {
      reader_.Fail(key_mark, "duplicate key " + Quote(key) + " in " + where,
                   "first given at line " + std::to_string(seen->second.key_mark.line));
    }
    entries_[key] = Entry{it->second, key_mark, reader_.At(it->second, key_mark)};
  }
}

Field MapReader::Get(const std::string& key) const {
  const Entry& e = entries_.at(key);
  return Field{e.value, e.value_mark, Path(key)};
}

void MapReader::Require(const std::string& key, const std::string& hint) const {
  if (Has(key)) return;
  const std::string where = field_.path.empty() ? "the experiment (top level)" : field_.path;
  reader_.Fail(field_.mark, "missing required key " + Quote(key) + " in " + where,
               hint.empty() ? "add '" + key + ": ...'" : hint);
}

Marks MapReader::marks() const {
  Marks m;
  m.self = field_.mark;
  for (const auto& [key, entry] : entries_) m.keys[key] = entry.value_mark;
  return m;
}

double YamlReader::Number(const Field& f) const {
  if (f.node.IsScalar() && !IsQuoted(f.node)) {
    if (const auto value = ToDouble(f.node.Scalar())) return *value;
  }
  Fail(f.mark, f.path + ": expected a number, got " + Describe(f.node),
       IsQuoted(f.node) ? "remove the quotes" : "e.g. 1.5, 2e-3, .inf or -.inf");
}

double YamlReader::Finite(const Field& f) const {
  const double x = Number(f);
  if (!std::isfinite(x)) Fail(f.mark, f.path + ": must be a finite number, got " + f.node.Scalar());
  return x;
}

double YamlReader::Positive(const Field& f) const {
  const double x = Finite(f);
  if (!(x > 0)) Fail(f.mark, f.path + ": must be > 0, got " + f.node.Scalar());
  return x;
}

double YamlReader::NonNegative(const Field& f) const {
  const double x = Finite(f);
  if (!(x >= 0)) Fail(f.mark, f.path + ": must be >= 0, got " + f.node.Scalar());
  return x;
}

long long YamlReader::Integer(const Field& f, long long min, long long max) const {
  std::optional<long long> value;
  if (f.node.IsScalar() && !IsQuoted(f.node)) value = ToInteger(f.node.Scalar());
  if (!value) {
    Fail(f.mark, f.path + ": expected an integer, got " + Describe(f.node),
         IsQuoted(f.node) ? "remove the quotes" : "a whole number without a decimal point");
  }
  if (*value < min || *value > max) {
    const std::string range = max >= std::numeric_limits<int>::max()
                                  ? ">= " + std::to_string(min)
                                  : "in " + std::to_string(min) + ".." + std::to_string(max);
    Fail(f.mark, f.path + ": must be " + range + ", got " + f.node.Scalar());
  }
  return *value;
}

bool YamlReader::Bool(const Field& f) const {
  if (f.node.IsScalar() && !IsQuoted(f.node)) {
    const std::string s = f.node.Scalar();
    if (s == "true" || s == "True" || s == "TRUE") return true;
    if (s == "false" || s == "False" || s == "FALSE") return false;
  }
  Fail(f.mark, f.path + ": expected true or false, got " + Describe(f.node));
}

std::string YamlReader::String(const Field& f) const {
  if (!f.node.IsScalar()) Fail(f.mark, f.path + ": expected a string, got " + Describe(f.node));
  return f.node.Scalar();
}

std::string YamlReader::Name(const Field& f) const {
  std::string s = String(f);
  if (s.empty()) Fail(f.mark, f.path + ": must not be empty");
  return s;
}

size_t YamlReader::Enum(const Field& f, const std::vector<std::string>& allowed) const {
  const std::string s = String(f);
  const auto it = std::find(allowed.begin(), allowed.end(), s);
  if (it == allowed.end()) {
    std::string hint;
    const std::string closest = ClosestName(s, allowed);
    if (!closest.empty()) hint = "did you mean '" + closest + "'? ";
    Fail(f.mark, f.path + ": " + Quote(s) + " is not one of " + JoinNames(allowed),
         hint + "allowed values: " + JoinNames(allowed));
  }
  return static_cast<size_t>(it - allowed.begin());
}

std::vector<Field> YamlReader::List(const Field& f) const {
  if (!f.node.IsSequence()) Fail(f.mark, f.path + ": expected a list, got " + Describe(f.node));
  std::vector<Field> items;
  for (size_t i = 0; i < f.node.size(); ++i) {
    const YAML::Node item = f.node[i];
    items.push_back(Field{item, At(item, f.mark), f.path + "[" + std::to_string(i) + "]"});
  }
  return items;
}

std::vector<double> YamlReader::Numbers(const Field& f) const {
  std::vector<double> out;
  for (const Field& item : List(f)) out.push_back(Finite(item));
  return out;
}

std::string YamlReader::ResolvePath(const Field& f) const {
  fs::path p(Name(f));
  if (p.is_relative()) p = base_dir_ / p;
  return p.lexically_normal().string();
}

void YamlReader::Bounds(const Field& f, double* lower, double* upper) const {
  const std::vector<Field> items = List(f);
  if (items.size() != 2) {
    Fail(f.mark,
         f.path + ": expected [lower, upper], got a list of " + std::to_string(items.size()) +
             " values",
         "use .inf / -.inf for a missing bound");
  }
  const double lo = Number(items[0]), hi = Number(items[1]);
  if (std::isnan(lo) || std::isnan(hi) || !(lo < hi)) {
    Fail(f.mark, f.path + ": lower bound " + FormatNumber(lo) + " must be < upper bound " +
                     FormatNumber(hi));
  }
  if (lo == kInf || hi == -kInf) Fail(f.mark, f.path + ": bounds leave no feasible value");
  *lower = lo;
  *upper = hi;
}

}  // namespace mjsysid::io
