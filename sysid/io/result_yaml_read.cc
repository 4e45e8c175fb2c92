// result.yaml read: the fields of result_fields.h read back in their order, each failure naming the
// file, the position and the key.
#include <yaml-cpp/yaml.h>

#include <cerrno>
#include <cmath>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <limits>
#include <optional>
#include <sstream>
#include <string>
#include <utility>
#include <vector>

#include "core/text.h"
#include "sysid/io/result_fields.h"
#include "sysid/io/result_internal.h"
#include "sysid/io/warnings.h"

namespace mjsysid::io::result_internal {
namespace {

// typed access to result.yaml with "FILE:LINE:COLUMN: key 'a.b': what" messages
class YamlReader {
 public:
  explicit YamlReader(std::string file) : file_(std::move(file)) {}

  [[noreturn]] void Fail(const YAML::Node& at, const std::string& key,
                         const std::string& what) const {
    std::string where = file_;
    if (at.IsDefined() && !at.Mark().is_null()) {
      where +=
          ":" + std::to_string(at.Mark().line + 1) + ":" + std::to_string(at.Mark().column + 1);
    }
    throw ResultError(where + ": key " + Quote(key) + ": " + what);
  }

  // map[key], which must exist
  YAML::Node Get(const YAML::Node& map, const std::string& key, const std::string& path) const {
    const YAML::Node node = map[key];
    if (!node.IsDefined()) Fail(map, path, "is missing");
    return node;
  }

  std::string Text(const YAML::Node& node, const std::string& path) const {
    if (node.IsNull()) return "";
    if (!node.IsScalar()) Fail(node, path, "expected text, found " + Kind(node));
    return node.Scalar();
  }

  double Double(const YAML::Node& node, const std::string& path) const {
    if (!node.IsScalar()) Fail(node, path, "expected a number, found " + Kind(node));
    const std::string& s = node.Scalar();
    // yaml's spellings of the special values
    if (s == ".inf" || s == ".Inf" || s == ".INF" || s == "+.inf" || s == "+.Inf" || s == "+.INF")
      return std::numeric_limits<double>::infinity();
    if (s == "-.inf" || s == "-.Inf" || s == "-.INF")
      return -std::numeric_limits<double>::infinity();
    if (s == ".nan" || s == ".NaN" || s == ".NAN") return std::numeric_limits<double>::quiet_NaN();
    char* end = nullptr;
    errno = 0;
    const double v = std::strtod(s.c_str(), &end);
    if (s.empty() || end != s.c_str() + s.size() ||
        std::isspace(static_cast<unsigned char>(s[0])) || !std::isfinite(v)) {
      Fail(node, path, "expected a number, found " + Quote(s));
    }
    return v;
  }

  int Int(const YAML::Node& node, const std::string& path) const {
    if (!node.IsScalar()) Fail(node, path, "expected an integer, found " + Kind(node));
    const std::string& s = node.Scalar();
    char* end = nullptr;
    errno = 0;
    const long long v = std::strtoll(s.c_str(), &end, 10);
    if (s.empty() || end != s.c_str() + s.size() || errno == ERANGE ||
        v < std::numeric_limits<int>::min() || v > std::numeric_limits<int>::max()) {
      Fail(node, path, "expected an integer, found " + Quote(s));
    }
    return static_cast<int>(v);
  }

  // a list of text
  std::vector<std::string> Texts(const YAML::Node& node, const std::string& path) const {
    if (node.IsNull()) return {};
    if (!node.IsSequence()) Fail(node, path, "expected a list, found " + Kind(node));
    std::vector<std::string> out;
    for (size_t i = 0; i < node.size(); ++i) {
      out.push_back(Text(node[i], path + "[" + std::to_string(i) + "]"));
    }
    return out;
  }

  // a map of text to text, in key order
  std::map<std::string, std::string> TextMap(const YAML::Node& node,
                                             const std::string& path) const {
    std::map<std::string, std::string> out;
    if (node.IsNull()) return out;
    if (!node.IsMap()) Fail(node, path, "expected a map, found " + Kind(node));
    for (const auto& kv : node) {
      const std::string key = Text(kv.first, path);
      out[key] = Text(kv.second, path + "." + key);
    }
    return out;
  }

  static std::string Kind(const YAML::Node& node) {
    if (node.IsSequence()) return "a list";
    if (node.IsMap()) return "a map";
    if (node.IsNull()) return "nothing";
    return Quote(node.Scalar());
  }

  const std::string& file() const { return file_; }

 private:
  std::string file_;
};

// a visitor of result_fields.h that reads each field from one YAML map (`map`, at `prefix`)
class FieldReader {
 public:
  FieldReader(const YamlReader& y, YAML::Node map, std::string prefix)
      : y_(y), map_(std::move(map)), prefix_(std::move(prefix)) {}

  void Text(const FieldKey& k, std::string& s) {
    if (const YAML::Node n = Find(k)) s = y_.Text(n, Path(k));
  }
  // the text and the kind's name (absent: none) as the record (SetRecord)
  template <class R>
  void Record(const FieldKey& k, const FieldKey& kind, R& record) {
    const YAML::Node n = Find(k);
    if (!n) return;
    const std::string text = y_.Text(n, Path(k));
    if (kind.name) {
      if (const YAML::Node named = Find(kind)) {
        const std::string name = y_.Text(named, Path(kind));
        if (!SetRecord(text, name, &record)) y_.Fail(named, Path(kind), "unknown " + Quote(name));
        return;
      }
    }
    SetRecord(text, std::nullopt, &record);
  }
  void Int(const FieldKey& k, int& i) {
    if (const YAML::Node n = Find(k)) i = y_.Int(n, Path(k));
  }
  void Number(const FieldKey& k, double& x) {
    if (const YAML::Node n = Find(k)) x = y_.Double(n, Path(k));
  }
  void Number(const FieldKey& k, std::optional<double>& x) {
    if (const YAML::Node n = Find(k)) x = y_.Double(n, Path(k));
  }
  // true or false, nothing else
  void Bool(const FieldKey& k, bool& b) {
    const YAML::Node n = Find(k);
    if (!n) return;
    const std::string text = y_.Text(n, Path(k));
    if (text != "true" && text != "false") {
      y_.Fail(n, Path(k), "expected true or false, found " + Quote(text));
    }
    b = text == "true";
  }
  // [low, high]
  void Pair(const FieldKey& k, double& low, double& high) {
    const YAML::Node n = Find(k);
    if (!n) return;
    if (!n.IsSequence() || n.size() != 2) {
      y_.Fail(n, Path(k), "expected [low, high], found " + YamlReader::Kind(n));
    }
    low = y_.Double(n[0], Path(k) + "[0]");
    high = y_.Double(n[1], Path(k) + "[1]");
  }
  void Numbers(const FieldKey& k, Eigen::VectorXd& v) {
    const YAML::Node n = Find(k);
    if (!n) return;
    if (!n.IsSequence()) {
      y_.Fail(n, Path(k), "expected a list of numbers, found " + YamlReader::Kind(n));
    }
    v.resize(static_cast<Eigen::Index>(n.size()));
    for (size_t i = 0; i < n.size(); ++i) {
      v[static_cast<Eigen::Index>(i)] = y_.Double(n[i], Path(k) + "[" + std::to_string(i) + "]");
    }
  }
  void Status(const FieldKey& k, FitStatus& s) {
    const YAML::Node n = Find(k);
    if (!n) return;
    const std::string name = y_.Text(n, Path(k));
    const std::optional<FitStatus> status = FitStatusFromName(name);
    if (!status) y_.Fail(n, Path(k), "unknown status " + Quote(name));
    s = *status;
  }
  void Flags(const FieldKey& k, bool& at_lower, bool& at_upper, bool& identifiable) {
    const YAML::Node n = Find(k);
    if (!n) return;
    for (const std::string& flag : y_.Texts(n, Path(k))) {
      if (flag == kFlags[0]) {
        at_lower = true;
      } else if (flag == kFlags[1]) {
        at_upper = true;
      } else if (flag == kFlags[2]) {
        identifiable = false;
      } else {
        y_.Fail(n, Path(k),
                "unknown flag " + Quote(flag) +
                    " (valid flags: at_lower_bound, at_upper_bound, unidentifiable)");
      }
    }
  }
  void Texts(const FieldKey& k, Style, std::vector<std::string>& items) {
    if (const YAML::Node n = Find(k)) items = y_.Texts(n, Path(k));
  }
  // the warnings, each group of the writer ({warning, count, sequences}) as the warnings it stands
  // for
  void Warnings(const FieldKey& k, std::vector<std::string>& items) {
    const YAML::Node n = Find(k);
    if (!n || n.IsNull()) return;
    if (!n.IsSequence()) y_.Fail(n, Path(k), "expected a list, found " + YamlReader::Kind(n));
    for (size_t i = 0; i < n.size(); ++i) {
      const std::string path = Path(k) + "[" + std::to_string(i) + "]";
      if (!n[i].IsMap()) {
        items.push_back(y_.Text(n[i], path));
        continue;
      }
      WarningGroup g;
      g.pattern = y_.Text(y_.Get(n[i], "warning", path + ".warning"), path + ".warning");
      g.sequences = y_.Texts(y_.Get(n[i], "sequences", path + ".sequences"), path + ".sequences");
      const int count = y_.Int(y_.Get(n[i], "count", path + ".count"), path + ".count");
      if (count != static_cast<int>(g.sequences.size()) ||
          g.pattern.find(kSequencePlaceholder) == std::string::npos) {
        y_.Fail(n[i], path,
                "expected a group of warnings {warning: TEXT with {sequence}, count: N, "
                "sequences: [N names]}, found count " +
                    std::to_string(count) + " and " + std::to_string(g.sequences.size()) +
                    " sequences");
      }
      for (size_t j = 0; j < g.sequences.size(); ++j) items.push_back(g.Expand(j));
    }
  }
  void TextMap(const FieldKey& k, Style, std::map<std::string, std::string>& map) {
    if (const YAML::Node n = Find(k)) map = y_.TextMap(n, Path(k));
  }
  template <class F>
  void Map(const FieldKey& k, Style, bool, F&& fields) {
    const YAML::Node n = Find(k);
    if (!n) return;
    if (!n.IsMap()) y_.Fail(n, Path(k), "expected a map, found " + YamlReader::Kind(n));
    FieldReader nested(y_, n, Path(k) + ".");
    fields(nested);
  }
  // a list of maps; nothing is an empty list
  template <class T, class F>
  void List(const FieldKey& k, Style, std::vector<T>& entries, F&& fields) {
    const YAML::Node n = Find(k);
    if (!n || n.IsNull()) return;
    if (!n.IsSequence()) y_.Fail(n, Path(k), "expected a list, found " + YamlReader::Kind(n));
    for (size_t i = 0; i < n.size(); ++i) {
      const std::string at = Path(k) + "[" + std::to_string(i) + "]";
      const YAML::Node entry = n[i];
      if (!entry.IsMap()) y_.Fail(entry, at, "expected a map, found " + YamlReader::Kind(entry));
      FieldReader nested(y_, entry, at + ".");
      fields(nested, entries.emplace_back());
    }
  }
  // written for the reader of the file; ReadResult recomputes them from result.h5's signals
  void FitMetrics(const FieldKey&, const FitResultFile&) {}

 private:
  std::string Path(const FieldKey& k) const { return prefix_ + k.name; }
  // the key's value; a missing required key fails, a missing optional one is an undefined node
  YAML::Node Find(const FieldKey& k) const {
    if (k.presence == Presence::kRequired) return y_.Get(map_, k.name, Path(k));
    return map_[k.name];
  }

  const YamlReader& y_;
  const YAML::Node map_;
  const std::string prefix_;
};

// the file's text as YAML, which must be a map
YAML::Node LoadMap(const std::string& path) {
  std::error_code ec;
  if (!std::filesystem::is_regular_file(path, ec)) {
    throw ResultError(path +
                      ": no such file (a fit writes result.yaml and result.h5 into its "
                      "output folder)");
  }
  std::ifstream in(path, std::ios::binary);
  std::stringstream text;
  text << in.rdbuf();
  if (!in) throw ResultError(path + ": cannot read the file: " + std::strerror(errno));
  YAML::Node root;
  try {
    root = YAML::Load(text.str());
  } catch (const YAML::Exception& e) {
    throw ResultError(path + ":" + std::to_string(e.mark.line + 1) + ":" +
                      std::to_string(e.mark.column + 1) + ": invalid YAML: " + e.msg);
  }
  if (!root.IsMap()) {
    throw ResultError(path + ": not an mjsysid result (expected a map with format: " + kFormat +
                      ")");
  }
  return root;
}

// format and format_version: an mjsysid result this build reads
void CheckFormat(const YamlReader& y, const YAML::Node& root) {
  const std::string format = y.Text(y.Get(root, "format", "format"), "format");
  if (format != kFormat) {
    y.Fail(root["format"], "format",
           "is " + Quote(format) + ", expected " + Quote(kFormat) + " (not an mjsysid result)");
  }
  const int version = y.Int(y.Get(root, "format_version", "format_version"), "format_version");
  if (version != kFormatVersion) {
    y.Fail(root["format_version"], "format_version",
           "version " + std::to_string(version) + " is not supported (this build reads version " +
               std::to_string(kFormatVersion) + ")");
  }
}

}  // namespace

void ReadYaml(const std::string& path, FitResultFile* r) {
  const YamlReader y(path);
  const YAML::Node root = LoadMap(path);
  CheckFormat(y, root);
  FieldReader reader(y, root, "");
  VisitResultFields(reader, *r);

  // the verdict from the status ("running" and other text: not converged); without
  // intervals_valid (files before it), the intervals are valid when converged
  r->outcome = FitStatusFromName(r->status).value_or(FitStatus::kNotConverged);
  r->converged = r->outcome == FitStatus::kConverged;
  r->interrupted = r->outcome == FitStatus::kInterrupted;
  if (!root["intervals_valid"]) r->intervals_valid = r->converged;
  // a solver that stopped before its first iteration: iterations 0 and costs .nan; files written
  // before said -1 iterations and costs -1 (Ceres' summary), read as the same
  if (r->iterations < 0) {
    r->iterations = 0;
    r->initial_cost = r->final_cost = std::numeric_limits<double>::quiet_NaN();
  }
  if (root["starts"] &&
      (r->best_start < 0 || r->best_start >= static_cast<int>(r->starts.size()))) {
    y.Fail(root["starts"]["best"], "starts.best",
           "is " + std::to_string(r->best_start) + ", not one of the " +
               std::to_string(r->starts.size()) + " runs");
  }
  CheckParameters(*r, path);
}

}  // namespace mjsysid::io::result_internal
