#include "sysid/io/experiment.h"

#include <yaml-cpp/yaml.h>

#include <algorithm>
#include <cctype>
#include <cerrno>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <set>
#include <sstream>
#include <utility>

namespace mjsysid::io {
namespace {

namespace fs = std::filesystem;

constexpr double kInf = std::numeric_limits<double>::infinity();

// at most this many names are listed in a hint
constexpr size_t kMaxListed = 20;

// ---------------------------------------------------------------------------------------------
// text helpers

std::string Lower(std::string s) {
  for (char& c : s) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  return s;
}

// levenshtein distance, case-insensitive
size_t EditDistance(const std::string& a_in, const std::string& b_in) {
  const std::string a = Lower(a_in), b = Lower(b_in);
  std::vector<size_t> row(b.size() + 1);
  for (size_t j = 0; j <= b.size(); ++j) row[j] = j;
  for (size_t i = 1; i <= a.size(); ++i) {
    size_t diagonal = row[0];
    row[0] = i;
    for (size_t j = 1; j <= b.size(); ++j) {
      const size_t up = row[j];
      row[j] = std::min({row[j] + 1, row[j - 1] + 1, diagonal + (a[i - 1] == b[j - 1] ? 0 : 1)});
      diagonal = up;
    }
  }
  return row[b.size()];
}

// the option closest to word, or "" when none is close enough to be a likely typo
std::string Closest(const std::string& word, const std::vector<std::string>& options) {
  const size_t limit = std::max<size_t>(2, word.size() / 3);
  std::string best;
  size_t best_distance = limit + 1;
  for (const std::string& option : options) {
    const size_t d = EditDistance(word, option);
    if (d < best_distance) {
      best = option;
      best_distance = d;
    }
  }
  return best;
}

// "a, b, c" (the first kMaxListed, then "... (N more)"), or "(none)"
std::string JoinNames(const std::vector<std::string>& names) {
  if (names.empty()) return "(none)";
  std::string out;
  for (size_t i = 0; i < names.size() && i < kMaxListed; ++i) {
    if (i > 0) out += ", ";
    out += names[i];
  }
  if (names.size() > kMaxListed) {
    out += ", ... (" + std::to_string(names.size() - kMaxListed) + " more)";
  }
  return out;
}

// "did you mean 'x'? valid <what>: a, b, c" (without the first part when nothing is close)
std::string NamesHint(const std::string& word, const std::vector<std::string>& options,
                      const std::string& what) {
  std::string hint;
  const std::string closest = Closest(word, options);
  if (!closest.empty()) hint = "did you mean '" + closest + "'? ";
  return hint + "valid " + what + ": " + JoinNames(options);
}

std::string FormatNumber(double x) {
  if (std::isinf(x)) return x > 0 ? ".inf" : "-.inf";
  std::ostringstream out;
  out.precision(10);
  out << x;
  return out.str();
}

std::string Quote(const std::string& s) { return "'" + s + "'"; }

// ---------------------------------------------------------------------------------------------
// scalar conversion (YAML 1.2 core schema numbers; quoted scalars are strings)

std::optional<double> ToDouble(const std::string& s) {
  const std::string lower = Lower(s);
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

// how a node looks, for type errors: "a map", "a list", "the string 'abc'", ...
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
// parsing

// a value being read: the node, where it is, and its dotted path for messages
struct Field {
  YAML::Node node;
  Mark mark;
  std::string path;
};

class Parser;

// the keys of one YAML map: checks type, unknown and duplicate keys on construction
class MapReader {
 public:
  MapReader(const Parser& parser, const Field& field, std::vector<std::string> keys);

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
  const Parser& parser_;
  Field field_;
  std::vector<std::string> keys_;
  std::map<std::string, Entry> entries_;
};

class Parser {
 public:
  // file: as named in marks; base_dir: for relative paths; default_name: when `name` is absent
  Parser(std::string file, fs::path base_dir, std::string default_name)
      : file_(std::move(file)),
        base_dir_(std::move(base_dir)),
        default_name_(std::move(default_name)) {}

  ExperimentConfig Parse(const YAML::Node& root);

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

  // a map of arbitrary names to finite numbers, in file order
  std::vector<NamedValue> NamedValues(const Field& f) const;

 private:
  void ParseModels(const MapReader& root, ExperimentConfig* c) const;
  void ParseData(const Field& f, ExperimentConfig* c) const;
  void ParseSequences(const Field& f, ExperimentConfig* c) const;
  void ParseSensors(const Field& f, ExperimentConfig* c) const;
  ParameterSpec ParseParameter(const Field& f, const ExperimentConfig& c) const;
  MeasurementSpec ParseMeasurement(const Field& f, const ExperimentConfig& c) const;
  void ParseTerm(const Field& f, bool is_delay, FitMeasurement::Term* term, Marks* marks) const;
  void ParseSolver(const Field& f, ExperimentConfig* c) const;
  void ParseSimulate(const Field& f, const ExperimentConfig& c, SimulateOptions* s) const;
  Excitation ParseExcitation(const Field& f, bool needs_actuator) const;

  std::string file_;
  fs::path base_dir_;
  std::string default_name_;
};

MapReader::MapReader(const Parser& parser, const Field& field, std::vector<std::string> keys)
    : parser_(parser), field_(field), keys_(std::move(keys)) {
  const std::string where = field_.path.empty() ? "the experiment" : field_.path;
  if (!field_.node.IsMap()) {
    parser_.Fail(field_.mark, where + ": expected a map, got " + Describe(field_.node),
                 "valid keys: " + JoinNames(keys_));
  }
  for (auto it = field_.node.begin(); it != field_.node.end(); ++it) {
    const Mark key_mark = parser_.At(it->first, field_.mark);
    if (!it->first.IsScalar()) {
      parser_.Fail(key_mark, where + ": keys must be plain names, got " + Describe(it->first),
                   "valid keys: " + JoinNames(keys_));
    }
    const std::string key = it->first.Scalar();
    if (std::find(keys_.begin(), keys_.end(), key) == keys_.end()) {
      parser_.Fail(key_mark, "unknown key " + Quote(key) + " in " + where,
                   NamesHint(key, keys_, "keys of " + where));
    }
    if (const auto seen = entries_.find(key); seen != entries_.end()) {
      parser_.Fail(key_mark, "duplicate key " + Quote(key) + " in " + where,
                   "first given at line " + std::to_string(seen->second.key_mark.line));
    }
    entries_[key] = Entry{it->second, key_mark, parser_.At(it->second, key_mark)};
  }
}

Field MapReader::Get(const std::string& key) const {
  const Entry& e = entries_.at(key);
  return Field{e.value, e.value_mark, Path(key)};
}

void MapReader::Require(const std::string& key, const std::string& hint) const {
  if (Has(key)) return;
  const std::string where = field_.path.empty() ? "the experiment (top level)" : field_.path;
  parser_.Fail(field_.mark, "missing required key " + Quote(key) + " in " + where,
               hint.empty() ? "add '" + key + ": ...'" : hint);
}

Marks MapReader::marks() const {
  Marks m;
  m.self = field_.mark;
  for (const auto& [key, entry] : entries_) m.keys[key] = entry.value_mark;
  return m;
}

double Parser::Number(const Field& f) const {
  if (f.node.IsScalar() && !IsQuoted(f.node)) {
    if (const auto value = ToDouble(f.node.Scalar())) return *value;
  }
  Fail(f.mark, f.path + ": expected a number, got " + Describe(f.node),
       IsQuoted(f.node) ? "remove the quotes" : "e.g. 1.5, 2e-3, .inf or -.inf");
}

double Parser::Finite(const Field& f) const {
  const double x = Number(f);
  if (!std::isfinite(x)) Fail(f.mark, f.path + ": must be a finite number, got " + f.node.Scalar());
  return x;
}

double Parser::Positive(const Field& f) const {
  const double x = Finite(f);
  if (!(x > 0)) Fail(f.mark, f.path + ": must be > 0, got " + f.node.Scalar());
  return x;
}

double Parser::NonNegative(const Field& f) const {
  const double x = Finite(f);
  if (!(x >= 0)) Fail(f.mark, f.path + ": must be >= 0, got " + f.node.Scalar());
  return x;
}

long long Parser::Integer(const Field& f, long long min, long long max) const {
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

bool Parser::Bool(const Field& f) const {
  if (f.node.IsScalar() && !IsQuoted(f.node)) {
    const std::string s = f.node.Scalar();
    if (s == "true" || s == "True" || s == "TRUE") return true;
    if (s == "false" || s == "False" || s == "FALSE") return false;
  }
  Fail(f.mark, f.path + ": expected true or false, got " + Describe(f.node));
}

std::string Parser::String(const Field& f) const {
  if (!f.node.IsScalar()) Fail(f.mark, f.path + ": expected a string, got " + Describe(f.node));
  return f.node.Scalar();
}

std::string Parser::Name(const Field& f) const {
  std::string s = String(f);
  if (s.empty()) Fail(f.mark, f.path + ": must not be empty");
  return s;
}

size_t Parser::Enum(const Field& f, const std::vector<std::string>& allowed) const {
  const std::string s = String(f);
  const auto it = std::find(allowed.begin(), allowed.end(), s);
  if (it == allowed.end()) {
    std::string hint;
    const std::string closest = Closest(s, allowed);
    if (!closest.empty()) hint = "did you mean '" + closest + "'? ";
    Fail(f.mark, f.path + ": " + Quote(s) + " is not one of " + JoinNames(allowed),
         hint + "allowed values: " + JoinNames(allowed));
  }
  return static_cast<size_t>(it - allowed.begin());
}

std::vector<Field> Parser::List(const Field& f) const {
  if (!f.node.IsSequence()) Fail(f.mark, f.path + ": expected a list, got " + Describe(f.node));
  std::vector<Field> items;
  for (size_t i = 0; i < f.node.size(); ++i) {
    const YAML::Node item = f.node[i];
    items.push_back(Field{item, At(item, f.mark), f.path + "[" + std::to_string(i) + "]"});
  }
  return items;
}

std::vector<double> Parser::Numbers(const Field& f) const {
  std::vector<double> out;
  for (const Field& item : List(f)) out.push_back(Finite(item));
  return out;
}

std::string Parser::ResolvePath(const Field& f) const {
  fs::path p(Name(f));
  if (p.is_relative()) p = base_dir_ / p;
  return p.lexically_normal().string();
}

void Parser::Bounds(const Field& f, double* lower, double* upper) const {
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

std::vector<NamedValue> Parser::NamedValues(const Field& f) const {
  if (!f.node.IsMap()) {
    Fail(f.mark, f.path + ": expected a map of names to numbers, got " + Describe(f.node));
  }
  std::vector<NamedValue> out;
  for (auto it = f.node.begin(); it != f.node.end(); ++it) {
    const Mark key_mark = At(it->first, f.mark);
    const std::string name = Name(Field{it->first, key_mark, f.path + " key"});
    for (const NamedValue& seen : out) {
      if (seen.name == name) {
        Fail(key_mark, "duplicate key " + Quote(name) + " in " + f.path,
             "first given at line " + std::to_string(seen.mark.line));
      }
    }
    const double value = Finite(Field{it->second, At(it->second, key_mark), f.path + "." + name});
    out.push_back(NamedValue{name, value, key_mark});
  }
  return out;
}

// ---------------------------------------------------------------------------------------------
// sections

const std::vector<std::string> kRootKeys = {
    "version",     "name",     "model",      "models",      "data",          "sequences",
    "sensor_time", "sensors",  "parameters", "measurement", "initial_state", "multiple_shooting",
    "solver",      "simulate", "output"};
const std::vector<std::string> kParameterKeys = {"name",  "target",  "object", "field",
                                                 "index", "initial", "bounds", "transform",
                                                 "scale", "prior",   "models"};
const std::vector<std::string> kSensorTimes = {"pre", "post"};
const std::vector<std::string> kTransforms = {"none", "log", "scale"};
// in the order of core's JacobianMode
const std::vector<std::string> kJacobianModes = {"auto", "directional", "matrix", "whole_rollout"};
const std::vector<std::string> kDifferences = {"forward", "central"};
const std::vector<std::string> kLossTypes = {"none", "huber", "cauchy"};
const std::vector<std::string> kExcitationTypes = {"sines", "chirp", "prbs", "zero"};

// core's ParameterError as a ConfigError at the parameter's key it is about, with core's message
// (followed by context) and hint
ConfigError AtSpecPart(const ParameterSpec& p, const ParameterError& e,
                       const std::string& context = {}) {
  const char* key = "";
  switch (e.part()) {
    case ParameterSpecPart::kKind:
      key = "target";
      break;
    case ParameterSpecPart::kObject:
      key = "object";
      break;
    case ParameterSpecPart::kField:
      key = "field";
      break;
    case ParameterSpecPart::kIndex:
      key = "index";
      break;
    case ParameterSpecPart::kNone:
      break;
  }
  return ConfigError(p.marks.Of(key), e.message() + context, e.hint());
}

ExperimentConfig Parser::Parse(const YAML::Node& root) {
  ExperimentConfig c;
  c.source_file = file_;
  c.base_dir = base_dir_.string();
  if (!root.IsDefined() || root.IsNull()) {
    Fail(Mark{file_, 1, 1}, "the experiment file is empty",
         "it needs at least 'model' and 'parameters'; see docs/experiment-schema.md");
  }
  const MapReader r(*this, Field{root, At(root), ""}, kRootKeys);
  c.marks = r.marks();

  // version and name
  if (r.Has("version")) {
    c.version = static_cast<int>(
        Integer(r.Get("version"), kExperimentSchemaVersion, kExperimentSchemaVersion));
  }
  c.name = r.Has("name") ? Name(r.Get("name")) : default_name_;
  if (c.name.empty()) c.name = "experiment";

  ParseModels(r, &c);
  if (r.Has("data")) ParseData(r.Get("data"), &c);
  if (r.Has("sequences")) ParseSequences(r.Get("sequences"), &c);
  if (r.Has("sensor_time")) {
    c.sensor_time = static_cast<SensorTime>(Enum(r.Get("sensor_time"), kSensorTimes));
  }
  if (r.Has("sensors")) ParseSensors(r.Get("sensors"), &c);

  // parameters: unique names
  if (r.Has("parameters")) {
    for (const Field& item : List(r.Get("parameters"))) {
      ParameterSpec p = ParseParameter(item, c);
      if (const ParameterSpec* first = c.FindParameter(p.name)) {
        Fail(p.marks.Of("name"), "duplicate parameter name " + Quote(p.name),
             "first defined at line " + std::to_string(first->marks.Of("name").line) +
                 "; parameter names must be unique");
      }
      c.parameters.push_back(std::move(p));
    }
  }

  // measurement: one entry per sensor
  if (r.Has("measurement")) {
    for (const Field& item : List(r.Get("measurement"))) {
      MeasurementSpec ms = ParseMeasurement(item, c);
      for (const MeasurementSpec& seen : c.measurement) {
        if (seen.sensor == ms.sensor) {
          Fail(ms.marks.Of("sensor"), "duplicate measurement entry for sensor " + Quote(ms.sensor),
               "first given at line " + std::to_string(seen.marks.Of("sensor").line));
        }
      }
      c.measurement.push_back(std::move(ms));
    }
  }

  // something must be fitted
  bool fits_measurement = false;
  for (const MeasurementSpec& ms : c.measurement) {
    fits_measurement |= ms.delay.fit || ms.gain.fit || ms.bias.fit;
  }
  if (c.parameters.empty() && !fits_measurement) {
    Fail(r.Has("parameters") ? r.Get("parameters").mark : c.marks.self, "no parameters to identify",
         "add a 'parameters' list, or set 'fit: true' on a measurement delay, gain or bias");
  }

  if (r.Has("initial_state")) {
    const MapReader s(*this, r.Get("initial_state"), {"estimate"});
    if (s.Has("estimate")) c.options.estimate_initial_state = Bool(s.Get("estimate"));
  }
  if (r.Has("multiple_shooting")) {
    const MapReader s(*this, r.Get("multiple_shooting"), {"segment_steps", "continuity_weight"});
    if (s.Has("segment_steps")) {
      c.options.segment_steps =
          static_cast<int>(Integer(s.Get("segment_steps"), 0, std::numeric_limits<int>::max()));
    }
    if (s.Has("continuity_weight")) {
      c.options.continuity_weight = Positive(s.Get("continuity_weight"));
    }
  }
  c.options.verbose = true;  // a file's default; `solver: {verbose: false}` turns it off
  if (r.Has("solver")) ParseSolver(r.Get("solver"), &c);
  if (r.Has("simulate")) ParseSimulate(r.Get("simulate"), c, &c.simulate);

  // output folder
  if (r.Has("output")) {
    c.output = ResolvePath(r.Get("output"));
  } else {
    c.output = (base_dir_ / "results" / c.name).lexically_normal().string();
  }
  return c;
}

void Parser::ParseModels(const MapReader& r, ExperimentConfig* c) const {
  const std::string hint =
      "give 'model: path/to/model.xml', or 'models:' as a list of {name, path}";
  if (r.Has("model") && r.Has("models")) {
    Fail(r.KeyMark("models"), "both 'model' and 'models' are given", "keep one: " + hint);
  }
  if (!r.Has("model") && !r.Has("models")) {
    Fail(c->marks.self, "missing required key 'model' (or 'models') in the experiment (top level)",
         hint);
  }
  if (r.Has("model")) {
    const Field f = r.Get("model");
    ModelSpec spec;
    spec.path = ResolvePath(f);
    spec.name = fs::path(spec.path).stem().string();
    spec.marks.self = f.mark;
    c->models.push_back(std::move(spec));
    return;
  }
  c->model_list = true;
  const std::vector<Field> items = List(r.Get("models"));
  if (items.empty()) Fail(r.Get("models").mark, "models: the list is empty", hint);
  for (const Field& item : items) {
    const MapReader m(*this, item, {"name", "path"});
    m.Require("name");
    m.Require("path");
    ModelSpec spec;
    spec.name = Name(m.Get("name"));
    spec.path = ResolvePath(m.Get("path"));
    spec.marks = m.marks();
    if (spec.name.find('/') != std::string::npos) {
      Fail(m.Get("name").mark, m.Path("name") + ": a model name must not contain '/'",
           "'/' separates model and sequence in 'sequences'");
    }
    if (const ModelSpec* first = c->FindModel(spec.name)) {
      Fail(m.Get("name").mark, "duplicate model name " + Quote(spec.name),
           "first defined at line " + std::to_string(first->marks.Of("name").line));
    }
    c->models.push_back(std::move(spec));
  }
}

void Parser::ParseData(const Field& f, ExperimentConfig* c) const {
  std::vector<Field> items;
  if (f.node.IsScalar()) {
    items.push_back(f);
  } else if (f.node.IsSequence()) {
    items = List(f);
  } else {
    Fail(f.mark,
         f.path + ": expected a file name or a list of file names, got " + Describe(f.node));
  }
  for (const Field& item : items) c->data.push_back(DataFile{ResolvePath(item), item.mark});
}

void Parser::ParseSequences(const Field& f, ExperimentConfig* c) const {
  std::vector<std::string> model_names;
  for (const ModelSpec& m : c->models) model_names.push_back(m.name);
  for (const Field& item : List(f)) {
    SequenceRef ref;
    ref.name = Name(item);
    ref.mark = item.mark;
    const size_t slash = ref.name.find('/');
    if (c->models.size() > 1 && slash != std::string::npos) {
      ref.model = ref.name.substr(0, slash);
      ref.name = ref.name.substr(slash + 1);
      if (!c->FindModel(ref.model)) {
        Fail(item.mark,
             item.path + ": unknown model " + Quote(ref.model) + " in " + Quote(item.node.Scalar()),
             NamesHint(ref.model, model_names, "models"));
      }
      if (ref.name.empty()) Fail(item.mark, item.path + ": the sequence name is empty");
    }
    for (const SequenceRef& seen : c->sequences) {
      if (seen.model == ref.model && seen.name == ref.name) {
        Fail(item.mark, "duplicate sequence " + Quote(item.node.Scalar()),
             "first given at line " + std::to_string(seen.mark.line));
      }
    }
    c->sequences.push_back(std::move(ref));
  }
}

void Parser::ParseSensors(const Field& f, ExperimentConfig* c) const {
  for (const Field& item : List(f)) {
    SensorSpec s;
    if (item.node.IsScalar()) {
      // a bare name: weight 1
      s.name = Name(item);
      s.marks.self = item.mark;
      s.marks.keys["name"] = item.mark;
    } else {
      const MapReader m(*this, item, {"name", "sigma", "weight"});
      m.Require("name");
      s.name = Name(m.Get("name"));
      s.marks = m.marks();
      if (m.Has("sigma") && m.Has("weight")) {
        Fail(m.KeyMark("weight"), item.path + ": give either 'sigma' or 'weight', not both",
             "weight = 1 / sigma");
      }
      if (m.Has("sigma")) s.sigma = Positive(m.Get("sigma"));
      if (m.Has("weight")) s.weight = Positive(m.Get("weight"));
    }
    for (const SensorSpec& seen : c->sensors) {
      if (seen.name == s.name) {
        Fail(s.marks.Of("name"), "duplicate sensor " + Quote(s.name),
             "first given at line " + std::to_string(seen.marks.Of("name").line));
      }
    }
    c->sensors.push_back(std::move(s));
  }
}

ParameterSpec Parser::ParseParameter(const Field& f, const ExperimentConfig& c) const {
  const MapReader r(*this, f, kParameterKeys);
  ParameterSpec p;
  p.marks = r.marks();
  r.Require("name");
  p.name = Name(r.Get("name"));
  p.target.label = p.name;
  r.Require("target", "one of: " + JoinNames(ParameterKindNames()));
  const ParameterKindInfo& info = ParameterKindTable()[Enum(r.Get("target"), ParameterKindNames())];
  const std::string kind = info.name;
  p.target.kind = kind;

  // object for the named kinds, field for `field`
  if (info.kind == ParameterKind::kField) {
    if (r.Has("object")) {
      Fail(r.KeyMark("object"), r.Path("object") + ": not used by target 'field'",
           "name the mjModel array in 'field' and the element in 'index'");
    }
    r.Require("field", "the name of an mjModel array, e.g. 'field: dof_damping'");
    p.target.field = Name(r.Get("field"));
  } else {
    if (r.Has("field")) {
      Fail(r.KeyMark("field"), r.Path("field") + ": only used by target 'field', not " + kind,
           "name the MuJoCo object in 'object'");
    }
    r.Require("object", std::string("the MuJoCo name of the ") + info.object_name() + " that '" +
                            kind + "' applies to");
    p.target.object = Name(r.Get("object"));
  }

  // component: core's model-free check (the kind's index range)
  if (r.Has("index")) {
    p.target.index = static_cast<int>(Integer(r.Get("index"), 0, std::numeric_limits<int>::max()));
  }
  try {
    CheckParameterSpec(p.target);
  } catch (const ParameterError& e) {
    throw AtSpecPart(p, e);
  }

  // value, bounds, transform
  r.Require("initial", "the starting value of the fit");
  const Field fi = r.Get("initial");
  p.initial = Finite(fi);
  if (r.Has("bounds")) {
    Bounds(r.Get("bounds"), &p.lower, &p.upper);
    if (p.initial < p.lower || p.initial > p.upper) {
      Fail(fi.mark,
           fi.path + ": " + FormatNumber(p.initial) + " is outside bounds [" +
               FormatNumber(p.lower) + ", " + FormatNumber(p.upper) + "]",
           "the bounds are given at line " + std::to_string(r.Get("bounds").mark.line));
    }
  }
  if (r.Has("transform"))
    p.transform = static_cast<Transform>(Enum(r.Get("transform"), kTransforms));
  if (r.Has("scale")) p.scale = Positive(r.Get("scale"));
  if (p.transform == Transform::kLog) {
    const Field ft = r.Get("transform");
    if (std::isfinite(p.lower) && !(p.lower > 0)) {
      Fail(ft.mark, ft.path + ": log needs a lower bound > 0, got " + FormatNumber(p.lower),
           "raise the lower bound above 0, or use transform: none or scale");
    }
    if (!(p.initial > 0)) {
      Fail(ft.mark, ft.path + ": log needs initial > 0, got " + FormatNumber(p.initial),
           "use transform: none or scale for parameters that can be <= 0");
    }
  }

  // prior
  if (r.Has("prior")) {
    const MapReader pr(*this, r.Get("prior"), {"mean", "sigma"});
    pr.Require("mean");
    pr.Require("sigma", "the prior's standard deviation, > 0");
    p.Prior(Finite(pr.Get("mean")), Positive(pr.Get("sigma")));
    p.prior_marks = pr.marks();
  }

  // models it applies to
  if (r.Has("models")) {
    std::vector<std::string> model_names;
    for (const ModelSpec& m : c.models) model_names.push_back(m.name);
    const std::vector<Field> items = List(r.Get("models"));
    if (items.empty()) {
      Fail(r.Get("models").mark, r.Path("models") + ": the list is empty",
           "leave 'models' out to apply the parameter to every model");
    }
    for (const Field& item : items) {
      const std::string name = Name(item);
      if (!c.FindModel(name)) {
        Fail(item.mark, item.path + ": unknown model " + Quote(name),
             NamesHint(name, model_names, "models"));
      }
      if (std::find(p.models.begin(), p.models.end(), name) != p.models.end()) {
        Fail(item.mark, item.path + ": model " + Quote(name) + " is listed twice");
      }
      p.models.push_back(name);
    }
  }
  return p;
}

void Parser::ParseTerm(const Field& f, bool is_delay, FitMeasurement::Term* term,
                       Marks* marks) const {
  const MapReader r(*this, f, {"initial", "fit", "bounds"});
  *marks = r.marks();
  if (r.Has("initial")) term->initial = Finite(r.Get("initial"));
  if (r.Has("fit")) term->fit = Bool(r.Get("fit"));
  if (r.Has("bounds")) {
    const Field fb = r.Get("bounds");
    Bounds(fb, &term->lower, &term->upper);
    if (is_delay && term->lower < 0) {
      Fail(fb.mark,
           fb.path + ": a delay cannot be negative, lower bound " + FormatNumber(term->lower),
           "delays are in seconds, >= 0");
    }
  }
  if (term->initial < term->lower || term->initial > term->upper) {
    const Mark& at = marks->Of("initial");
    Fail(at,
         r.Path("initial") + ": " + FormatNumber(term->initial) + " is outside bounds [" +
             FormatNumber(term->lower) + ", " + FormatNumber(term->upper) + "]",
         is_delay ? "delays are in seconds, >= 0" : "widen the bounds or change initial");
  }
}

MeasurementSpec Parser::ParseMeasurement(const Field& f, const ExperimentConfig& c) const {
  const MapReader r(*this, f, {"sensor", "delay", "gain", "bias"});
  MeasurementSpec ms;
  ms.marks = r.marks();
  r.Require("sensor");
  const Field fs = r.Get("sensor");
  ms.sensor = Name(fs);
  if (!c.sensors.empty()) {
    std::vector<std::string> names;
    for (const SensorSpec& s : c.sensors) names.push_back(s.name);
    if (std::find(names.begin(), names.end(), ms.sensor) == names.end()) {
      Fail(fs.mark, fs.path + ": sensor " + Quote(ms.sensor) + " is not in 'sensors'",
           NamesHint(ms.sensor, names, "sensors"));
    }
  }
  if (r.Has("delay")) ParseTerm(r.Get("delay"), true, &ms.delay, &ms.delay_marks);
  if (r.Has("gain")) ParseTerm(r.Get("gain"), false, &ms.gain, &ms.gain_marks);
  if (r.Has("bias")) ParseTerm(r.Get("bias"), false, &ms.bias, &ms.bias_marks);
  return ms;
}

void Parser::ParseSolver(const Field& f, ExperimentConfig* c) const {
  const MapReader r(
      *this, f,
      {"max_iterations", "function_tolerance", "gradient_tolerance", "parameter_tolerance",
       "jacobian", "differences", "relative_step", "threads", "loss", "verbose"});
  c->solver_marks = r.marks();
  FitOptions* o = &c->options;
  const long long kIntMax = std::numeric_limits<int>::max();
  if (r.Has("max_iterations")) {
    o->max_iterations = static_cast<int>(Integer(r.Get("max_iterations"), 1, kIntMax));
  }
  if (r.Has("function_tolerance")) o->function_tolerance = NonNegative(r.Get("function_tolerance"));
  if (r.Has("gradient_tolerance")) o->gradient_tolerance = NonNegative(r.Get("gradient_tolerance"));
  if (r.Has("parameter_tolerance")) {
    o->parameter_tolerance = NonNegative(r.Get("parameter_tolerance"));
  }
  if (r.Has("jacobian")) {
    o->jacobian.mode = static_cast<JacobianMode>(Enum(r.Get("jacobian"), kJacobianModes));
  }
  if (r.Has("differences")) o->jacobian.central = Enum(r.Get("differences"), kDifferences) == 1;
  if (r.Has("relative_step")) o->jacobian.relative_step = Positive(r.Get("relative_step"));
  if (r.Has("threads")) o->threads = static_cast<int>(Integer(r.Get("threads"), 0, kIntMax));
  if (r.Has("loss")) {
    const MapReader l(*this, r.Get("loss"), {"type", "scale"});
    if (l.Has("type")) o->loss = static_cast<LossType>(Enum(l.Get("type"), kLossTypes));
    if (l.Has("scale")) o->loss_scale = Positive(l.Get("scale"));
  }
  if (r.Has("verbose")) o->verbose = Bool(r.Get("verbose"));
}

Excitation Parser::ParseExcitation(const Field& f, bool needs_actuator) const {
  const MapReader r(*this, f,
                    {"actuator", "type", "amplitude", "frequencies", "f0", "f1", "switch_period"});
  Excitation e;
  e.marks = r.marks();
  if (needs_actuator) {
    r.Require("actuator", "in a list, each excitation names its actuator");
  }
  if (r.Has("actuator")) e.actuator = Name(r.Get("actuator"));
  if (r.Has("type")) e.type = static_cast<ExcitationType>(Enum(r.Get("type"), kExcitationTypes));
  if (r.Has("amplitude")) e.amplitude = NonNegative(r.Get("amplitude"));
  if (r.Has("frequencies")) {
    const Field ff = r.Get("frequencies");
    e.frequencies.clear();
    for (const Field& item : List(ff)) e.frequencies.push_back(Positive(item));
    if (e.frequencies.empty() && e.type == ExcitationType::kSines) {
      Fail(ff.mark, ff.path + ": sines need at least one frequency");
    }
  }
  if (r.Has("f0")) e.f0 = Positive(r.Get("f0"));
  if (r.Has("f1")) e.f1 = Positive(r.Get("f1"));
  if (r.Has("switch_period")) e.switch_period = Positive(r.Get("switch_period"));
  return e;
}

void Parser::ParseSimulate(const Field& f, const ExperimentConfig& c, SimulateOptions* s) const {
  const MapReader r(
      *this, f, {"truth", "sequences", "steps", "seed", "excitation", "noise", "initial_state"});
  s->marks = r.marks();
  const long long kIntMax = std::numeric_limits<int>::max();

  // truth: values of declared parameters
  if (r.Has("truth")) {
    s->truth = NamedValues(r.Get("truth"));
    std::vector<std::string> names;
    for (const ParameterSpec& p : c.parameters) names.push_back(p.name);
    for (const NamedValue& t : s->truth) {
      if (!c.FindParameter(t.name)) {
        Fail(t.mark, r.Path("truth") + ": " + Quote(t.name) + " is not a parameter",
             NamesHint(t.name, names, "parameters"));
      }
    }
  }
  if (r.Has("sequences")) s->sequences = static_cast<int>(Integer(r.Get("sequences"), 1, kIntMax));
  if (r.Has("steps")) s->steps = static_cast<int>(Integer(r.Get("steps"), 1, kIntMax));
  if (r.Has("seed")) {
    s->seed = static_cast<std::uint64_t>(
        Integer(r.Get("seed"), 0, std::numeric_limits<long long>::max()));
  }

  // excitation: one map for all actuators, or a list with one map per actuator
  if (r.Has("excitation")) {
    const Field fe = r.Get("excitation");
    s->excitation.clear();
    if (fe.node.IsSequence()) {
      for (const Field& item : List(fe)) {
        Excitation e = ParseExcitation(item, true);
        for (const Excitation& seen : s->excitation) {
          if (seen.actuator == e.actuator) {
            Fail(e.marks.Of("actuator"), "duplicate excitation for actuator " + Quote(e.actuator),
                 "first given at line " + std::to_string(seen.marks.Of("actuator").line));
          }
        }
        s->excitation.push_back(std::move(e));
      }
      if (s->excitation.empty()) Fail(fe.mark, fe.path + ": the list is empty");
    } else {
      s->excitation.push_back(ParseExcitation(fe, false));
    }
  }

  // noise: sensor -> sigma
  if (r.Has("noise")) {
    s->noise = NamedValues(r.Get("noise"));
    for (const NamedValue& n : s->noise) {
      if (n.value < 0) {
        Fail(n.mark, r.Path("noise") + "." + n.name + ": a noise sigma must be >= 0, got " +
                         FormatNumber(n.value));
      }
    }
  }

  if (r.Has("initial_state")) {
    const MapReader is(*this, r.Get("initial_state"), {"qpos", "qvel"});
    s->initial_state.marks = is.marks();
    if (is.Has("qpos")) s->initial_state.qpos = Numbers(is.Get("qpos"));
    if (is.Has("qvel")) s->initial_state.qvel = Numbers(is.Get("qvel"));
  }
}

// ---------------------------------------------------------------------------------------------
// model checks

// the names of a model's objects of one type, in id order (unnamed ones left out)
std::vector<std::string> ObjectNames(const mjModel& m, mjtObj type, long long count) {
  std::vector<std::string> names;
  for (long long i = 0; i < count; ++i) {
    const char* name = mj_id2name(&m, type, static_cast<int>(i));
    if (name && *name) names.push_back(name);
  }
  return names;
}

// the id of a named object, or a ConfigError at mark
int RequireObject(const mjModel& m, mjtObj type, long long count, const std::string& what,
                  const std::string& name, const Mark& mark, const std::string& model_label) {
  const int id = mj_name2id(&m, type, name.c_str());
  if (id < 0) {
    throw ConfigError(mark, "no " + what + " named " + Quote(name) + " in " + model_label,
                      NamesHint(name, ObjectNames(m, type, count), what + " names"));
  }
  return id;
}

// a parameter resolved against m by core; its ParameterError as a ConfigError
void ValidateParameter(const ParameterSpec& p, const mjModel& m, const std::string& label) {
  try {
    Parameter::Resolve(m, p.target);
  } catch (const ParameterError& e) {
    throw AtSpecPart(p, e, " in " + label);
  }
}

void CheckSensor(const mjModel& m, const std::string& name, const Mark& mark,
                 const std::string& label) {
  RequireObject(m, mjOBJ_SENSOR, m.nsensor, "sensor", name, mark, label);
}

void CheckSize(const std::vector<double>& values, long long expected, const Mark& mark,
               const std::string& what, const std::string& label) {
  if (!values.empty() && static_cast<long long>(values.size()) != expected) {
    throw ConfigError(mark,
                      what + " has " + std::to_string(values.size()) + " values, " + label +
                          " needs " + std::to_string(expected),
                      "leave it out to start from the model's default");
  }
}

}  // namespace

// ---------------------------------------------------------------------------------------------
// public api

std::string Mark::ToString() const {
  if (line <= 0) return file;
  return file + ":" + std::to_string(line) + ":" + std::to_string(column);
}

const Mark& Marks::Of(const std::string& key) const {
  const auto it = keys.find(key);
  return it == keys.end() ? self : it->second;
}

ConfigError::ConfigError(Mark mark, std::string message, std::string hint)
    : std::runtime_error(mark.ToString() + ": " + message +
                         (hint.empty() ? "" : " (hint: " + hint + ")")),
      mark_(std::move(mark)),
      message_(std::move(message)),
      hint_(std::move(hint)) {}

std::vector<const ParameterSpec*> ExperimentConfig::ParametersOf(
    const std::string& model_name) const {
  std::vector<const ParameterSpec*> out;
  for (const ParameterSpec& p : parameters) {
    if (p.AppliesTo(model_name)) out.push_back(&p);
  }
  return out;
}

const ParameterSpec* ExperimentConfig::FindParameter(const std::string& param_name) const {
  for (const ParameterSpec& p : parameters) {
    if (p.name == param_name) return &p;
  }
  return nullptr;
}

const ModelSpec* ExperimentConfig::FindModel(const std::string& model_name) const {
  for (const ModelSpec& m : models) {
    if (m.name == model_name) return &m;
  }
  return nullptr;
}

ExperimentConfig ParseExperiment(const std::string& yaml_text,
                                 const std::string& path_for_messages) {
  // the file as named in messages; the absolute directory for relative paths
  const fs::path source =
      path_for_messages.empty() ? fs::path("experiment.yaml") : fs::path(path_for_messages);
  const fs::path absolute = fs::absolute(source).lexically_normal();
  const std::string file = path_for_messages.empty() ? "<experiment>" : path_for_messages;
  Parser parser(file, absolute.parent_path(), source.stem().string());

  YAML::Node root;
  try {
    root = YAML::Load(yaml_text);
  } catch (const YAML::Exception& e) {
    const Mark mark =
        e.mark.is_null() ? Mark{file, 0, 0} : Mark{file, e.mark.line + 1, e.mark.column + 1};
    throw ConfigError(mark, "YAML syntax error: " + e.msg,
                      "check indentation (spaces, not tabs), brackets and quotes");
  }
  ExperimentConfig config = parser.Parse(root);
  config.source_file = absolute.string();
  return config;
}

ExperimentConfig LoadExperiment(const std::string& path) {
  std::error_code ec;
  const Mark mark{path, 0, 0};
  if (!fs::exists(path, ec)) {
    throw ConfigError(
        mark, "experiment file not found: " + path,
        "relative paths are relative to the current directory " + fs::current_path(ec).string());
  }
  if (!fs::is_regular_file(path, ec)) {
    throw ConfigError(mark, "not a regular file: " + path, "give the path of a .yaml file");
  }
  // size cap: yaml-cpp needs ~150 bytes of memory and ~1 us per byte (50 MB: 7.7 GiB, 59 s)
  const char* cap_env = std::getenv("MJSYSID_MAX_YAML_BYTES");
  const std::uintmax_t cap = cap_env ? std::strtoull(cap_env, nullptr, 10) : 1u << 20;
  if (fs::file_size(path, ec) > cap) {
    throw ConfigError(mark,
                      "experiment file of " + std::to_string(fs::file_size(path, ec)) +
                          " bytes is larger than the limit of " + std::to_string(cap) + " bytes",
                      "experiments are a few KB; set MJSYSID_MAX_YAML_BYTES to raise the limit");
  }
  std::ifstream in(path, std::ios::binary);
  std::ostringstream text;
  text << in.rdbuf();
  if (!in.good() && !in.eof()) {
    throw ConfigError(mark, "cannot read experiment file: " + path, "check its permissions");
  }
  return ParseExperiment(text.str(), path);
}

void ValidateExperimentAgainstModel(const ExperimentConfig& config, const mjModel& m,
                                    const std::string& model_name) {
  // which model of the experiment this is
  const ModelSpec* spec = model_name.empty() ? nullptr : config.FindModel(model_name);
  if (!model_name.empty() && !spec) {
    std::vector<std::string> names;
    for (const ModelSpec& s : config.models) names.push_back(s.name);
    throw ConfigError(config.marks.Of(config.model_list ? "models" : "model"),
                      "model " + Quote(model_name) + " is not part of the experiment",
                      NamesHint(model_name, names, "models"));
  }
  const std::string label =
      spec ? "model " + Quote(spec->name) + " (" + spec->path + ")" : std::string("the model");

  // sensors, parameters, measurement
  for (const SensorSpec& s : config.sensors) CheckSensor(m, s.name, s.marks.Of("name"), label);
  for (const ParameterSpec& p : config.parameters) {
    if (p.AppliesTo(model_name)) ValidateParameter(p, m, label);
  }
  for (const MeasurementSpec& ms : config.measurement) {
    CheckSensor(m, ms.sensor, ms.marks.Of("sensor"), label);
  }

  // simulate: noise sensors, excitation actuators, initial state sizes
  const SimulateOptions& sim = config.simulate;
  for (const NamedValue& n : sim.noise) CheckSensor(m, n.name, n.mark, label);
  for (const Excitation& e : sim.excitation) {
    if (!e.actuator.empty()) {
      RequireObject(m, mjOBJ_ACTUATOR, m.nu, "actuator", e.actuator, e.marks.Of("actuator"), label);
    }
  }
  CheckSize(sim.initial_state.qpos, static_cast<long long>(m.nq),
            sim.initial_state.marks.Of("qpos"), "simulate.initial_state.qpos", label + " (nq)");
  CheckSize(sim.initial_state.qvel, static_cast<long long>(m.nv),
            sim.initial_state.marks.Of("qvel"), "simulate.initial_state.qvel", label + " (nv)");
}

void CheckModelFilesExist(const ExperimentConfig& config) {
  for (const ModelSpec& spec : config.models) {
    std::error_code ec;
    const Mark& at = config.model_list ? spec.marks.Of("path") : spec.marks.self;
    if (!fs::exists(spec.path, ec)) {
      throw ConfigError(
          at, "model file not found: " + spec.path,
          "relative paths are relative to the experiment file's directory " + config.base_dir);
    }
    if (!fs::is_regular_file(spec.path, ec)) {
      throw ConfigError(at, "model path is not a regular file: " + spec.path);
    }
  }
}

}  // namespace mjsysid::io
