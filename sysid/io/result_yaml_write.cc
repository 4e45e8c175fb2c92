// result.yaml written: the fields of result_fields.h emitted in their order.
#include <yaml-cpp/yaml.h>

#include <algorithm>
#include <string>
#include <vector>

#include "sysid/io/result_fields.h"
#include "sysid/io/result_internal.h"
#include "sysid/io/warnings.h"

namespace mjsysid::io::result_internal {
namespace {

// a visitor of result_fields.h that emits each field as `key: value` into one YAML map
class YamlWriter {
 public:
  explicit YamlWriter(YAML::Emitter& out) : out_(out) {}

  void Text(const FieldKey& k, const std::string& s) {
    if (k.presence == Presence::kWhenSet && s.empty()) return;
    Key(k) << s;
  }
  // the text, then the kind's name (when known)
  template <class R>
  void Record(const FieldKey& k, const FieldKey& kind, const R& record) {
    Text(k, RecordText(record));
    if (kind.name) Text(kind, RecordKind(record));
  }
  void Int(const FieldKey& k, int i) { Key(k) << i; }
  void Bool(const FieldKey& k, bool b) { Key(k) << b; }
  void Number(const FieldKey& k, double x) { Key(k) << result_internal::Number(x); }
  void Number(const FieldKey& k, const std::optional<double>& x) {
    if (x) Number(k, *x);
  }
  void Pair(const FieldKey& k, double low, double high) {
    Key(k) << YAML::Flow << YAML::BeginSeq << result_internal::Number(low)
           << result_internal::Number(high) << YAML::EndSeq;
  }
  void Numbers(const FieldKey& k, const Eigen::VectorXd& v) {
    Key(k) << YAML::Flow << YAML::BeginSeq;
    for (Eigen::Index i = 0; i < v.size(); ++i) out_ << result_internal::Number(v[i]);
    out_ << YAML::EndSeq;
  }
  void Status(const FieldKey& k, FitStatus s) { Key(k) << FitStatusName(s); }
  void Flags(const FieldKey& k, bool at_lower, bool at_upper, bool identifiable) {
    Key(k) << YAML::Flow << YAML::BeginSeq;
    if (at_lower) out_ << kFlags[0];
    if (at_upper) out_ << kFlags[1];
    if (!identifiable) out_ << kFlags[2];
    out_ << YAML::EndSeq;
  }
  void Texts(const FieldKey& k, Style style, const std::vector<std::string>& items) {
    Key(k);
    Layout(style, items.empty()) << YAML::BeginSeq;
    for (const std::string& item : items) out_ << item;
    out_ << YAML::EndSeq;
  }
  // one line per warning, except the ones that recur per sequence: one map per group,
  // {warning: TEXT with {sequence}, count: N, sequences: [names]}
  void Warnings(const FieldKey& k, const std::vector<std::string>& items) {
    Key(k);
    Layout(Style::kBlockOrEmptyFlow, items.empty()) << YAML::BeginSeq;
    for (const WarningGroup& g : GroupWarnings(items)) {
      if (g.Count() <= 1) {
        for (size_t i = 0; i < std::max<size_t>(g.sequences.size(), 1); ++i) out_ << g.Expand(i);
        continue;
      }
      out_ << YAML::BeginMap << YAML::Key << "warning" << YAML::Value << g.pattern;
      out_ << YAML::Key << "count" << YAML::Value << g.Count();
      out_ << YAML::Key << "sequences" << YAML::Value << YAML::Flow << YAML::BeginSeq;
      for (const std::string& name : g.sequences) out_ << name;
      out_ << YAML::EndSeq << YAML::EndMap;
    }
    out_ << YAML::EndSeq;
  }
  void TextMap(const FieldKey& k, Style style, const std::map<std::string, std::string>& map) {
    Key(k);
    Layout(style, map.empty()) << YAML::BeginMap;
    for (const auto& [key, value] : map) out_ << YAML::Key << key << YAML::Value << value;
    out_ << YAML::EndMap;
  }
  template <class F>
  void Map(const FieldKey& k, Style style, bool written, F&& fields) {
    if (!written) return;
    Key(k);
    Layout(style, false) << YAML::BeginMap;
    fields(*this);
    out_ << YAML::EndMap;
  }
  template <class T, class F>
  void List(const FieldKey& k, Style entry_style, const std::vector<T>& entries, F&& fields) {
    if (k.presence == Presence::kWhenSet && entries.empty()) return;
    Key(k) << YAML::BeginSeq;
    for (const T& entry : entries) {
      Layout(entry_style, false) << YAML::BeginMap;
      fields(*this, entry);
      out_ << YAML::EndMap;
    }
    out_ << YAML::EndSeq;
  }
  // per sequence and channel: the % fit and NRMSE at the start and at the estimate
  void FitMetrics(const FieldKey& k, const FitResultFile& r) {
    Key(k);
    Layout(Style::kBlockOrEmptyFlow, r.sequences.empty() && r.validation.empty()) << YAML::BeginSeq;
    for (const std::vector<SequenceResult>* list : {&r.sequences, &r.validation}) {
      for (const SequenceResult& s : *list) {
        out_ << YAML::BeginMap;
        VisitFitMetricsFields(*this, s, list == &r.sequences ? "fit" : "validation");
        out_ << YAML::EndMap;
      }
    }
    out_ << YAML::EndSeq;
  }

 private:
  YAML::Emitter& Key(const FieldKey& k) { return out_ << YAML::Key << k.name << YAML::Value; }
  // flow for kFlow, and for kBlockOrEmptyFlow when empty
  YAML::Emitter& Layout(Style style, bool empty) {
    if (style == Style::kFlow || (style == Style::kBlockOrEmptyFlow && empty)) out_ << YAML::Flow;
    return out_;
  }

  YAML::Emitter& out_;
};

}  // namespace

std::string EmitYaml(const FitResultFile& r) {
  YAML::Emitter out;
  out.SetIndent(2);
  out << YAML::Comment("mjsysid fit result (layout: sysid/io/result.h)");
  out << YAML::BeginMap;
  out << YAML::Key << "format" << YAML::Value << kFormat;
  out << YAML::Key << "format_version" << YAML::Value << kFormatVersion;
  YamlWriter writer(out);
  VisitResultFields(writer, r);
  out << YAML::EndMap;
  if (!out.good()) throw ResultError("cannot format result.yaml: " + out.GetLastError());
  return std::string(out.c_str()) + "\n";
}

}  // namespace mjsysid::io::result_internal
