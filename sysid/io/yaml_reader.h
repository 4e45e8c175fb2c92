// Reading YAML with positions: the typed, position-aware readers behind the experiment schema
// (sysid/io/experiment*.cc). Every failure is a ConfigError at the offending element
// (file:line:column, 1-based) saying what was expected and what was found.
// Internal to sysid/io: it exposes yaml-cpp types.
#pragma once

#include <yaml-cpp/yaml.h>

#include <filesystem>
#include <map>
#include <optional>
#include <string>
#include <vector>

#include "core/text.h"
#include "sysid/io/marks.h"

namespace mjsysid::io {

// a number as the schema prints it in messages (.inf / -.inf, 10 significant digits)
std::string FormatNumber(double x);
// how a node looks, for type errors: "a map", "a list", "the string 'abc'", ...
std::string Describe(const YAML::Node& n);

// a value being read: the node, where it is, and its dotted path for messages
struct Field {
  YAML::Node node;
  Mark mark;
  std::string path;
};

class YamlReader;

// the keys of one YAML map: checks type, unknown and duplicate keys on construction
class MapReader {
 public:
  MapReader(const YamlReader& reader, const Field& field, std::vector<std::string> keys);

  bool Has(const std::string& key) const { return entries_.count(key) > 0; }
  // the value of a key that Has(); its mark is the key's when the value is empty
  Field Get(const std::string& key) const;
  // the position of a key itself
  const Mark& KeyMark(const std::string& key) const { return entries_.at(key).key_mark; }
  // throws "missing required key" unless Has(key)
  void Require(const std::string& key, const std::string& hint = {}) const;
  std::string Path(const std::string& key) const {
    return field_.path.empty() ? key : field_.path + "." + key;
  }
  const Field& field() const { return field_; }
  Marks marks() const;

 private:
  struct Entry {
    YAML::Node value;
    Mark key_mark;
    Mark value_mark;
  };
  const YamlReader& reader_;
  Field field_;
  std::vector<std::string> keys_;
  std::map<std::string, Entry> entries_;
};

// Reads one YAML file's values: positions (marks), typed scalars and lists with messages that
// name the value's path, what was expected and what was found (ConfigError at the value).
class YamlReader {
 public:
  // file: as named in marks; base_dir: for relative paths
  YamlReader(std::string file, std::filesystem::path base_dir)
      : file_(std::move(file)), base_dir_(std::move(base_dir)) {}

  Mark At(const YAML::Node& n, const Mark& fallback) const {
    if (!n.IsDefined() || n.IsNull() || n.Mark().is_null()) return fallback;
    return Mark{file_, n.Mark().line + 1, n.Mark().column + 1};
  }
  Mark At(const YAML::Node& n) const { return At(n, Mark{file_, 1, 1}); }

  [[noreturn]] void Fail(const Mark& mark, const std::string& message,
                         const std::string& hint = {}) const {
    throw ConfigError(mark, message, hint);
  }

  // typed scalar readers; all fail with the value's path, what was expected and what was found
  double Number(const Field& f) const;
  double Finite(const Field& f) const;
  double Positive(const Field& f) const;
  double NonNegative(const Field& f) const;
  long long Integer(const Field& f, long long min, long long max) const;
  bool Bool(const Field& f) const;
  std::string String(const Field& f) const;
  std::string Name(const Field& f) const;  // a non-empty string
  size_t Enum(const Field& f, const std::vector<std::string>& allowed) const;
  std::vector<Field> List(const Field& f) const;
  std::vector<double> Numbers(const Field& f) const;
  std::string ResolvePath(const Field& f) const;

  // [lower, upper] with lower < upper
  void Bounds(const Field& f, double* lower, double* upper) const;

 protected:
  std::string file_;
  std::filesystem::path base_dir_;
};

}  // namespace mjsysid::io
