#include "sysid/io/result.h"

#include <hdf5.h>
#include <yaml-cpp/yaml.h>

#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <limits>
#include <mutex>
#include <set>
#include <sstream>
#include <string>
#include <utility>
#include <vector>

#include "core/text.h"
#include "sysid/io/atomic_file.h"
#include "sysid/io/hdf5_util.h"
#include "sysid/io/result_internal.h"

namespace mjsysid::io {
namespace result_internal {

// ---------------------------------------------------------------------------------------------
// messages and numbers

// "<file>: <where>: <what>"
[[noreturn]] void Fail(const std::string& file, const std::string& where, const std::string& what) {
  throw ResultError(file + (where.empty() ? "" : ": " + where) + ": " + what);
}

// the shortest of %.15g..%.17g that reads back as x; YAML's .inf, -.inf, .nan otherwise
std::string Number(double x) {
  if (std::isnan(x)) return ".nan";
  if (std::isinf(x)) return x > 0 ? ".inf" : "-.inf";
  return FormatShortest(x);
}

// ---------------------------------------------------------------------------------------------
// checks shared by the writers and the reader

void CheckParameters(const FitResultFile& r, const std::string& file) {
  std::set<std::string> seen;
  for (size_t i = 0; i < r.parameters.size(); ++i) {
    const std::string& name = r.parameters[i].name;
    const std::string where = "parameters[" + std::to_string(i) + "]";
    if (name.empty()) Fail(file, where, "the parameter name is empty");
    if (name.find('\0') != std::string::npos) Fail(file, where, "the name contains a NUL");
    if (!seen.insert(name).second) Fail(file, where, "two parameters are named " + Quote(name));
  }
}

// a T x cols matrix of a sequence
void CheckSequenceMatrix(const RowMatrix& m, Eigen::Index rows, Eigen::Index cols,
                         const std::string& file, const std::string& object) {
  if (m.rows() != rows || m.cols() != cols) {
    Fail(file, object,
         "has shape (" + std::to_string(m.rows()) + ", " + std::to_string(m.cols()) +
             "), expected (" + std::to_string(rows) + ", " + std::to_string(cols) +
             ") = (samples in time, columns of the sensors)");
  }
}

void CheckSequence(const SequenceResult& s, const std::string& file, const std::string& where) {
  const std::string g = where + "/" + s.name;
  if (s.name.empty() || s.name == "." || s.name.find('/') != std::string::npos ||
      s.name.find('\0') != std::string::npos) {
    Fail(file, g, "sequence name " + Quote(s.name) + " is not a valid group name");
  }
  if (s.sensor_names.size() != s.sensor_dims.size()) {
    Fail(file, g,
         std::to_string(s.sensor_names.size()) + " sensor names but " +
             std::to_string(s.sensor_dims.size()) + " sensor dims");
  }
  Eigen::Index cols = 0;
  for (size_t i = 0; i < s.sensor_dims.size(); ++i) {
    if (s.sensor_dims[i] < 1) {
      Fail(file, g,
           "sensor " + Quote(s.sensor_names[i]) + " has dimension " +
               std::to_string(s.sensor_dims[i]) + " (must be >= 1)");
    }
    cols += s.sensor_dims[i];
  }
  const Eigen::Index samples = s.time.size();
  CheckSequenceMatrix(s.measured, samples, cols, file, g + "/measured");
  CheckSequenceMatrix(s.simulated_initial, samples, cols, file, g + "/simulated_initial");
  CheckSequenceMatrix(s.simulated_final, samples, cols, file, g + "/simulated_final");
}

// sizes tying the trace, covariance and jacobian to the parameters
void CheckMatrices(const FitResultFile& r, const std::string& file) {
  const auto np = static_cast<Eigen::Index>(r.parameters.size());
  const std::string nps = std::to_string(np);

  // trace: every entry holds np values, or none holds any
  const size_t width = r.trace.empty() ? 0 : r.trace[0].parameters.size();
  for (size_t i = 0; i < r.trace.size(); ++i) {
    const size_t n = r.trace[i].parameters.size();
    if (n != width || (n != 0 && n != r.parameters.size())) {
      Fail(file, "/trace/parameters",
           "trace entry " + std::to_string(i) + " holds " + std::to_string(n) +
               " parameter values, expected " + nps + " (or none in every entry)");
    }
  }

  // covariance np x np (or 0 x 0: not computed), jacobian nres x np (or 0 x 0)
  const bool cov_empty =
      r.uncertainty.covariance.rows() == 0 && r.uncertainty.covariance.cols() == 0;
  if (!cov_empty &&
      (r.uncertainty.covariance.rows() != np || r.uncertainty.covariance.cols() != np)) {
    Fail(file, "/covariance",
         "has shape (" + std::to_string(r.uncertainty.covariance.rows()) + ", " +
             std::to_string(r.uncertainty.covariance.cols()) + "), expected (" + nps + ", " + nps +
             ") for " + nps + " parameters (or (0, 0))");
  }
  const bool jac_empty = r.jacobian.rows() == 0 && r.jacobian.cols() == 0;
  if (!jac_empty && r.jacobian.cols() != np) {
    Fail(file, "/jacobian",
         "has " + std::to_string(r.jacobian.cols()) + " columns, expected " + nps +
             " (one per parameter)");
  }
}

// every check of the arrays: matrices, then sequences (valid, unique names; consistent shapes)
void CheckArrays(const FitResultFile& r, const std::string& file) {
  CheckMatrices(r, file);
  std::set<std::string> seen;
  for (const SequenceResult& s : r.sequences) {
    if (!seen.insert(s.name).second) {
      Fail(file, "/sequences/" + s.name, "two sequences are named " + Quote(s.name));
    }
    CheckSequence(s, file);
  }
  for (const SequenceResult& s : r.validation) {
    if (!seen.insert(s.name).second) {
      Fail(file, "/validation/" + s.name, "two sequences are named " + Quote(s.name));
    }
    CheckSequence(s, file, "/validation");
  }
}

}  // namespace result_internal

namespace {

using namespace result_internal;  // NOLINT(build/namespaces): this file's own internals

// ---------------------------------------------------------------------------------------------
// result.yaml

std::string EmitYaml(const FitResultFile& r) {
  YAML::Emitter out;
  out.SetIndent(2);
  out << YAML::Comment("mjsysid fit result (layout: sysid/io/result.h)");
  out << YAML::BeginMap;

  // summary
  out << YAML::Key << "format" << YAML::Value << kFormat;
  out << YAML::Key << "format_version" << YAML::Value << kFormatVersion;
  const std::pair<const char*, const std::string*> texts[] = {
      {"name", &r.name},
      {"experiment", &r.experiment},
      {"status", &r.status},
      {"termination", &r.termination},
      {"created", &r.created},
      {"mjsysid_version", &r.mjsysid_version},
      {"mujoco_version", &r.mujoco_version},
      {"jacobian_mode", &r.jacobian_mode}};
  for (const auto& [key, value] : texts) out << YAML::Key << key << YAML::Value << *value;
  if (!r.run_id.empty()) out << YAML::Key << "run_id" << YAML::Value << r.run_id;
  // whether std and ci95 mean something (only for status converged)
  out << YAML::Key << "intervals_valid" << YAML::Value << r.intervals_valid;
  out << YAML::Key << "iterations" << YAML::Value << r.iterations;
  out << YAML::Key << "initial_cost" << YAML::Value << Number(r.initial_cost);
  out << YAML::Key << "final_cost" << YAML::Value << Number(r.final_cost);
  out << YAML::Key << "residual_variance" << YAML::Value << Number(r.uncertainty.residual_variance);
  out << YAML::Key << "num_residuals" << YAML::Value << r.num_residuals;
  out << YAML::Key << "wall_time_s" << YAML::Value << Number(r.seconds);
  // multiple shooting as used (0: single shooting) and why
  out << YAML::Key << "segment_steps_used" << YAML::Value << r.segment_steps_used;
  out << YAML::Key << "segment_reason" << YAML::Value << r.segment_reason;
  // whether the interval check ran and why (sysid/interval_check.h); absent: no uncertainty step
  if (!r.interval_check.empty()) {
    out << YAML::Key << "interval_check" << YAML::Value << r.interval_check;
  }
  // the statistical stop before the last Jacobian (sysid/gn_convergence.h): the covariance's
  // Jacobian is the previous iterate's; absent: the estimate's own
  if (r.covariance_jacobian_iteration >= 0) {
    out << YAML::Key << "covariance_jacobian" << YAML::Value << YAML::BeginMap;
    out << YAML::Key << "iteration" << YAML::Value << r.covariance_jacobian_iteration;
    out << YAML::Key << "last_step_std_errors" << YAML::Value << Number(r.last_step_std_errors);
    out << YAML::EndMap;
  }
  // auto's contact segments: the cells next to contact events left out (sysid/event_windows.h)
  if (r.event_windows.masked > 0) {
    out << YAML::Key << "event_windows" << YAML::Value << YAML::BeginMap;
    out << YAML::Key << "window" << YAML::Value << r.event_windows.window;
    out << YAML::Key << "events" << YAML::Value << r.event_windows.events;
    out << YAML::Key << "masked_cells" << YAML::Value << r.event_windows.masked;
    out << YAML::Key << "sensors" << YAML::Value << YAML::Flow << r.event_windows.sensors;
    out << YAML::EndMap;
  }

  // solver settings, as text
  out << YAML::Key << "solver" << YAML::Value << YAML::BeginMap;
  for (const auto& [key, value] : r.solver) out << YAML::Key << key << YAML::Value << value;
  out << YAML::EndMap;

  // parameters
  out << YAML::Key << "parameters" << YAML::Value << YAML::BeginSeq;
  for (const ParameterEstimate& p : r.parameters) {
    out << YAML::BeginMap;
    out << YAML::Key << "name" << YAML::Value << p.name;
    out << YAML::Key << "value" << YAML::Value << Number(p.value);
    out << YAML::Key << "initial" << YAML::Value << Number(p.initial);
    out << YAML::Key << "std" << YAML::Value << Number(p.std_error);
    out << YAML::Key << "ci95" << YAML::Value << YAML::Flow << YAML::BeginSeq << Number(p.ci95_low)
        << Number(p.ci95_high) << YAML::EndSeq;
    out << YAML::Key << "flags" << YAML::Value << YAML::Flow << YAML::BeginSeq;
    if (p.at_lower) out << "at_lower_bound";
    if (p.at_upper) out << "at_upper_bound";
    if (!p.identifiable) out << "unidentifiable";
    out << YAML::EndSeq;
    if (p.truth) out << YAML::Key << "truth" << YAML::Value << Number(*p.truth);
    out << YAML::EndMap;
  }
  out << YAML::EndSeq;

  // quantities derived from the estimate (body_inertial: mass, com, principal moments)
  if (!r.derived.empty()) {
    out << YAML::Key << "derived" << YAML::Value << YAML::BeginSeq;
    for (const DerivedQuantity& d : r.derived) {
      out << YAML::BeginMap;
      out << YAML::Key << "name" << YAML::Value << d.name;
      out << YAML::Key << "unit" << YAML::Value << d.unit;
      out << YAML::Key << "value" << YAML::Value << Number(d.value);
      out << YAML::Key << "std" << YAML::Value << Number(d.std_error);
      out << YAML::Key << "ci95" << YAML::Value << YAML::Flow << YAML::BeginSeq
          << Number(d.ci95_low) << Number(d.ci95_high) << YAML::EndSeq;
      out << YAML::Key << "derived_from" << YAML::Value << d.derived_from;
      if (d.truth) out << YAML::Key << "truth" << YAML::Value << Number(*d.truth);
      out << YAML::EndMap;
    }
    out << YAML::EndSeq;
  }

  // lists of text, models
  const std::pair<const char*, const std::vector<std::string>*> lists[] = {
      {"unidentifiable", &r.uncertainty.unidentifiable}, {"warnings", &r.warnings}};
  for (const auto& [key, items] : lists) {
    out << YAML::Key << key << YAML::Value;
    if (items->empty()) out << YAML::Flow;
    out << YAML::BeginSeq;
    for (const std::string& item : *items) out << item;
    out << YAML::EndSeq;
  }
  out << YAML::Key << "identified_models" << YAML::Value;
  if (r.identified_models.empty()) out << YAML::Flow;
  out << YAML::BeginMap;
  for (const auto& [model, file] : r.identified_models) {
    out << YAML::Key << model << YAML::Value << file;
  }
  out << YAML::EndMap;

  // per channel fit metrics (sysid/metrics.h) of the fitted and the held-out sequences, for the
  // reader of the file (ReadResult recomputes them from result.h5's signals)
  out << YAML::Key << "fit_metrics" << YAML::Value;
  if (r.sequences.empty() && r.validation.empty()) out << YAML::Flow;
  out << YAML::BeginSeq;
  for (const std::vector<SequenceResult>* list : {&r.sequences, &r.validation}) {
    for (const SequenceResult& s : *list) {
      out << YAML::BeginMap;
      out << YAML::Key << "sequence" << YAML::Value << s.name;
      out << YAML::Key << "role" << YAML::Value << (list == &r.sequences ? "fit" : "validation");
      out << YAML::Key << "channels" << YAML::Value << YAML::BeginSeq;
      for (const ChannelFit& f : s.channel_fits) {
        out << YAML::Flow << YAML::BeginMap;
        out << YAML::Key << "channel" << YAML::Value << f.channel;
        out << YAML::Key << "fit_initial" << YAML::Value << Number(f.fit_initial);
        out << YAML::Key << "fit_final" << YAML::Value << Number(f.fit_final);
        out << YAML::Key << "nrmse_initial" << YAML::Value << Number(f.nrmse_initial);
        out << YAML::Key << "nrmse_final" << YAML::Value << Number(f.nrmse_final);
        out << YAML::EndMap;
      }
      out << YAML::EndSeq;
      out << YAML::EndMap;
    }
  }
  out << YAML::EndSeq;

  // multi-start: every start (values in the order of `parameters`), the best, the spread
  if (!r.starts.empty()) {
    const auto numbers = [&out](const Eigen::VectorXd& v) {
      out << YAML::Flow << YAML::BeginSeq;
      for (Eigen::Index i = 0; i < v.size(); ++i) out << Number(v[i]);
      out << YAML::EndSeq;
    };
    out << YAML::Key << "starts" << YAML::Value << YAML::BeginMap;
    out << YAML::Key << "best" << YAML::Value << r.best_start;
    out << YAML::Key << "runs" << YAML::Value << YAML::BeginSeq;
    for (const StartResult& st : r.starts) {
      out << YAML::BeginMap;
      out << YAML::Key << "start" << YAML::Value;
      numbers(st.start);
      out << YAML::Key << "estimate" << YAML::Value;
      numbers(st.estimate);
      out << YAML::Key << "initial_cost" << YAML::Value << Number(st.initial_cost);
      out << YAML::Key << "final_cost" << YAML::Value << Number(st.final_cost);
      out << YAML::Key << "status" << YAML::Value << FitStatusName(st.status);
      out << YAML::Key << "iterations" << YAML::Value << st.iterations;
      if (!st.error.empty()) out << YAML::Key << "error" << YAML::Value << st.error;
      out << YAML::EndMap;
    }
    out << YAML::EndSeq;
    out << YAML::Key << "spread" << YAML::Value << YAML::BeginSeq;
    for (const ParameterSpread& sp : r.start_spread) {
      out << YAML::Flow << YAML::BeginMap;
      out << YAML::Key << "name" << YAML::Value << sp.name;
      out << YAML::Key << "min" << YAML::Value << Number(sp.min);
      out << YAML::Key << "max" << YAML::Value << Number(sp.max);
      out << YAML::Key << "relative" << YAML::Value << Number(sp.relative);
      out << YAML::EndMap;
    }
    out << YAML::EndSeq;
    out << YAML::EndMap;
  }
  // the reduced model (FitOptions::reduce_model, core/reduced_model.h)
  const FitResult::Reduction& red = r.reduction;
  if (red.recorded) {
    out << YAML::Key << "reduced" << YAML::Value << YAML::Flow << YAML::BeginMap;
    out << YAML::Key << "used" << YAML::Value << red.used;
    out << YAML::Key << "collision_pairs" << YAML::Value << red.collision_pairs;
    out << YAML::Key << "collision_pairs_off" << YAML::Value << red.collision_pairs_off;
    out << YAML::Key << "geoms_off" << YAML::Value << red.geoms_off;
    out << YAML::Key << "disabled" << YAML::Value << YAML::Flow << red.disabled;
    out << YAML::Key << "guard_trips" << YAML::Value << red.guard_trips;
    out << YAML::EndMap;
  }
  out << YAML::EndMap;
  if (!out.good()) throw ResultError("cannot format result.yaml: " + out.GetLastError());
  return std::string(out.c_str()) + "\n";
}

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

// one entry of `derived:` (name, unit, value, std, ci95 [low, high], derived_from, truth?)
DerivedQuantity ReadDerived(const YamlReader& y, const YAML::Node& node, size_t index) {
  const std::string at = "derived[" + std::to_string(index) + "]";
  if (!node.IsMap()) y.Fail(node, at, "expected a map, found " + YamlReader::Kind(node));
  DerivedQuantity d;
  d.name = y.Text(y.Get(node, "name", at + ".name"), at + ".name");
  d.unit = y.Text(y.Get(node, "unit", at + ".unit"), at + ".unit");
  d.value = y.Double(y.Get(node, "value", at + ".value"), at + ".value");
  d.std_error = y.Double(y.Get(node, "std", at + ".std"), at + ".std");
  const YAML::Node ci = y.Get(node, "ci95", at + ".ci95");
  if (!ci.IsSequence() || ci.size() != 2) {
    y.Fail(ci, at + ".ci95", "expected [low, high], found " + YamlReader::Kind(ci));
  }
  d.ci95_low = y.Double(ci[0], at + ".ci95[0]");
  d.ci95_high = y.Double(ci[1], at + ".ci95[1]");
  d.derived_from = y.Text(y.Get(node, "derived_from", at + ".derived_from"), at + ".derived_from");
  if (node["truth"]) d.truth = y.Double(node["truth"], at + ".truth");
  return d;
}

ParameterEstimate ReadParameter(const YamlReader& y, const YAML::Node& node, size_t index) {
  const std::string path = "parameters[" + std::to_string(index) + "]";
  if (!node.IsMap()) y.Fail(node, path, "expected a map, found " + YamlReader::Kind(node));
  ParameterEstimate p;
  p.name = y.Text(y.Get(node, "name", path + ".name"), path + ".name");
  const std::string& at = path;
  p.value = y.Double(y.Get(node, "value", at + ".value"), at + ".value");
  p.initial = y.Double(y.Get(node, "initial", at + ".initial"), at + ".initial");
  p.std_error = y.Double(y.Get(node, "std", at + ".std"), at + ".std");

  // ci95: [low, high]
  const YAML::Node ci = y.Get(node, "ci95", at + ".ci95");
  if (!ci.IsSequence() || ci.size() != 2) {
    y.Fail(ci, at + ".ci95", "expected [low, high], found " + YamlReader::Kind(ci));
  }
  p.ci95_low = y.Double(ci[0], at + ".ci95[0]");
  p.ci95_high = y.Double(ci[1], at + ".ci95[1]");

  // flags
  const YAML::Node flags = y.Get(node, "flags", at + ".flags");
  for (const std::string& flag : y.Texts(flags, at + ".flags")) {
    if (flag == kFlags[0]) {
      p.at_lower = true;
    } else if (flag == kFlags[1]) {
      p.at_upper = true;
    } else if (flag == kFlags[2]) {
      p.identifiable = false;
    } else {
      y.Fail(flags, at + ".flags",
             "unknown flag " + Quote(flag) +
                 " (valid flags: at_lower_bound, at_upper_bound, unidentifiable)");
    }
  }

  // truth: optional
  const YAML::Node truth = node["truth"];
  if (truth.IsDefined()) p.truth = y.Double(truth, at + ".truth");
  return p;
}

// a list of numbers
Eigen::VectorXd ReadNumbers(const YamlReader& y, const YAML::Node& node, const std::string& path) {
  if (!node.IsSequence())
    y.Fail(node, path, "expected a list of numbers, found " + YamlReader::Kind(node));
  Eigen::VectorXd v(static_cast<Eigen::Index>(node.size()));
  for (size_t i = 0; i < node.size(); ++i) {
    v[static_cast<Eigen::Index>(i)] = y.Double(node[i], path + "[" + std::to_string(i) + "]");
  }
  return v;
}

// the multi-start block: best, runs, spread
void ReadStarts(const YamlReader& y, const YAML::Node& node, FitResultFile* r) {
  if (!node.IsMap()) y.Fail(node, "starts", "expected a map, found " + YamlReader::Kind(node));
  const YAML::Node runs = y.Get(node, "runs", "starts.runs");
  if (!runs.IsSequence())
    y.Fail(runs, "starts.runs", "expected a list, found " + YamlReader::Kind(runs));
  for (size_t i = 0; i < runs.size(); ++i) {
    const std::string at = "starts.runs[" + std::to_string(i) + "]";
    const YAML::Node n = runs[i];
    if (!n.IsMap()) y.Fail(n, at, "expected a map, found " + YamlReader::Kind(n));
    StartResult st;
    st.start = ReadNumbers(y, y.Get(n, "start", at + ".start"), at + ".start");
    st.estimate = ReadNumbers(y, y.Get(n, "estimate", at + ".estimate"), at + ".estimate");
    st.initial_cost =
        y.Double(y.Get(n, "initial_cost", at + ".initial_cost"), at + ".initial_cost");
    st.final_cost = y.Double(y.Get(n, "final_cost", at + ".final_cost"), at + ".final_cost");
    const std::string status = y.Text(y.Get(n, "status", at + ".status"), at + ".status");
    const std::optional<FitStatus> s = FitStatusFromName(status);
    if (!s) y.Fail(n["status"], at + ".status", "unknown status " + Quote(status));
    st.status = *s;
    st.iterations = y.Int(y.Get(n, "iterations", at + ".iterations"), at + ".iterations");
    if (n["error"]) st.error = y.Text(n["error"], at + ".error");
    r->starts.push_back(std::move(st));
  }
  r->best_start = y.Int(y.Get(node, "best", "starts.best"), "starts.best");
  if (r->best_start < 0 || r->best_start >= static_cast<int>(r->starts.size())) {
    y.Fail(node["best"], "starts.best",
           "is " + std::to_string(r->best_start) + ", not one of the " +
               std::to_string(r->starts.size()) + " runs");
  }
  const YAML::Node spread = y.Get(node, "spread", "starts.spread");
  if (!spread.IsSequence())
    y.Fail(spread, "starts.spread", "expected a list, found " + YamlReader::Kind(spread));
  for (size_t i = 0; i < spread.size(); ++i) {
    const std::string at = "starts.spread[" + std::to_string(i) + "]";
    const YAML::Node n = spread[i];
    if (!n.IsMap()) y.Fail(n, at, "expected a map, found " + YamlReader::Kind(n));
    ParameterSpread sp;
    sp.name = y.Text(y.Get(n, "name", at + ".name"), at + ".name");
    sp.min = y.Double(y.Get(n, "min", at + ".min"), at + ".min");
    sp.max = y.Double(y.Get(n, "max", at + ".max"), at + ".max");
    sp.relative = y.Double(y.Get(n, "relative", at + ".relative"), at + ".relative");
    r->start_spread.push_back(std::move(sp));
  }
}

void ReadYaml(const std::string& path, FitResultFile* r) {
  const YamlReader y(path);
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

  // format
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

  // summary
  const std::pair<const char*, std::string*> texts[] = {{"name", &r->name},
                                                        {"experiment", &r->experiment},
                                                        {"status", &r->status},
                                                        {"termination", &r->termination},
                                                        {"created", &r->created},
                                                        {"mjsysid_version", &r->mjsysid_version},
                                                        {"mujoco_version", &r->mujoco_version},
                                                        {"jacobian_mode", &r->jacobian_mode}};
  for (const auto& [key, value] : texts) *value = y.Text(y.Get(root, key, key), key);
  if (root["run_id"]) r->run_id = y.Text(root["run_id"], "run_id");
  // optional (results before automatic multiple shooting have neither)
  if (root["segment_reason"]) r->segment_reason = y.Text(root["segment_reason"], "segment_reason");
  if (root["interval_check"]) r->interval_check = y.Text(root["interval_check"], "interval_check");
  if (root["segment_steps_used"]) {
    const std::string steps = y.Text(root["segment_steps_used"], "segment_steps_used");
    try {
      r->segment_steps_used = std::stoi(steps);
    } catch (const std::exception&) {
      y.Fail(root["segment_steps_used"], "segment_steps_used",
             "expected an integer, found " + Quote(steps));
    }
  }
  // the verdict from the status ("running" and other text: not converged); intervals_valid is
  // optional (files before it: valid when converged)
  r->outcome = FitStatusFromName(r->status).value_or(FitStatus::kNotConverged);
  r->converged = r->outcome == FitStatus::kConverged;
  r->interrupted = r->outcome == FitStatus::kInterrupted;
  r->intervals_valid = r->converged;
  if (root["intervals_valid"]) {
    const std::string valid = y.Text(root["intervals_valid"], "intervals_valid");
    if (valid != "true" && valid != "false") {
      y.Fail(root["intervals_valid"], "intervals_valid",
             "expected true or false, found " + Quote(valid));
    }
    r->intervals_valid = valid == "true";
  }
  const std::pair<const char*, int*> ints[] = {{"iterations", &r->iterations},
                                               {"num_residuals", &r->num_residuals}};
  for (const auto& [key, value] : ints) *value = y.Int(y.Get(root, key, key), key);
  const std::pair<const char*, double*> doubles[] = {
      {"initial_cost", &r->initial_cost},
      {"final_cost", &r->final_cost},
      {"residual_variance", &r->uncertainty.residual_variance},
      {"wall_time_s", &r->seconds}};
  for (const auto& [key, value] : doubles) *value = y.Double(y.Get(root, key, key), key);
  r->solver = y.TextMap(y.Get(root, "solver", "solver"), "solver");
  // where the covariance's Jacobian was taken (optional: absent when at the estimate)
  if (const YAML::Node cj = root["covariance_jacobian"]) {
    r->covariance_jacobian_iteration = y.Int(
        y.Get(cj, "iteration", "covariance_jacobian.iteration"), "covariance_jacobian.iteration");
    r->last_step_std_errors =
        y.Double(y.Get(cj, "last_step_std_errors", "covariance_jacobian.last_step_std_errors"),
                 "covariance_jacobian.last_step_std_errors");
  }
  // event windows (optional: absent when none were left out)
  if (const YAML::Node ev = root["event_windows"]) {
    const std::pair<const char*, int*> counts[] = {{"window", &r->event_windows.window},
                                                   {"events", &r->event_windows.events},
                                                   {"masked_cells", &r->event_windows.masked}};
    for (const auto& [key, value] : counts) {
      const std::string at = std::string("event_windows.") + key;
      *value = y.Int(y.Get(ev, key, at), at);
    }
    const YAML::Node sensors = y.Get(ev, "sensors", "event_windows.sensors");
    if (!sensors.IsSequence()) {
      y.Fail(sensors, "event_windows.sensors",
             "expected a list, found " + YamlReader::Kind(sensors));
    }
    for (size_t i = 0; i < sensors.size(); ++i) {
      r->event_windows.sensors.push_back(y.Text(sensors[i], "event_windows.sensors"));
    }
  }

  // parameters
  const YAML::Node params = y.Get(root, "parameters", "parameters");
  if (!params.IsNull() && !params.IsSequence()) {
    y.Fail(params, "parameters", "expected a list, found " + YamlReader::Kind(params));
  }
  for (size_t i = 0; i < params.size(); ++i) {
    r->parameters.push_back(ReadParameter(y, params[i], i));
  }

  // derived quantities (optional: absent when nothing is derived)
  if (const YAML::Node derived = root["derived"]) {
    if (!derived.IsSequence()) {
      y.Fail(derived, "derived", "expected a list, found " + YamlReader::Kind(derived));
    }
    for (size_t i = 0; i < derived.size(); ++i) {
      r->derived.push_back(ReadDerived(y, derived[i], i));
    }
  }

  // lists, models
  r->uncertainty.unidentifiable =
      y.Texts(y.Get(root, "unidentifiable", "unidentifiable"), "unidentifiable");
  r->warnings = y.Texts(y.Get(root, "warnings", "warnings"), "warnings");
  r->identified_models =
      y.TextMap(y.Get(root, "identified_models", "identified_models"), "identified_models");
  if (root["starts"]) ReadStarts(y, root["starts"], r);
  // the reduced model (optional: results before it have none)
  if (const YAML::Node red = root["reduced"]) {
    FitResult::Reduction& o = r->reduction;
    o.recorded = true;
    o.used = y.Text(y.Get(red, "used", "reduced.used"), "reduced.used") == "true";
    const std::pair<const char*, int*> counts[] = {{"collision_pairs", &o.collision_pairs},
                                                   {"collision_pairs_off", &o.collision_pairs_off},
                                                   {"geoms_off", &o.geoms_off},
                                                   {"guard_trips", &o.guard_trips}};
    for (const auto& [key, value] : counts) {
      const std::string at = std::string("reduced.") + key;
      *value = y.Int(y.Get(red, key, at), at);
    }
    const YAML::Node disabled = y.Get(red, "disabled", "reduced.disabled");
    for (size_t i = 0; i < disabled.size(); ++i) {
      o.disabled.push_back(y.Text(disabled[i], "reduced.disabled"));
    }
  }
  CheckParameters(*r, path);
}

}  // namespace

// -----------------------------------------------------------------------------------------------

void WriteResultYaml(const std::string& path, const FitResultFile& result) {
  CheckParameters(result, path);
  const std::string text = EmitYaml(result);
  try {
    WriteFileAtomically(path, text);
  } catch (const FileError& e) {
    throw ResultError(e.what());
  }
}

namespace {

// HDF5's text of a failed system call ("... errno = 28, error message = '...' ...") as
// "<path>: cannot write: <the system's reason>"; other messages as they are
std::string WriteFailure(const std::string& path, const std::string& what) {
  const size_t at = what.find("errno = ");
  if (at == std::string::npos) return what;
  const int err = std::atoi(what.c_str() + at + 8);
  return path + ": cannot write: " + std::strerror(err);
}

}  // namespace

void WriteResultH5(const std::string& path, const FitResultFile& result) {
  CheckParameters(result, path);
  CheckMatrices(result, path);  // the sequences are checked as they are written
  std::lock_guard<std::mutex> lock(h5::Mutex());
  h5::Silence();
  try {
    ReplaceAtomically(path, [&](const std::string& tmp) { WriteH5(tmp, result, path); });
  } catch (const h5::Error& e) {
    throw ResultError(WriteFailure(path, e.what()));
  } catch (const FileError& e) {
    throw ResultError(e.what());
  }
}

std::string RunIdComment(const std::string& run_id) {
  return "<!-- mjsysid run " + run_id + " -->";
}

FitResultFile ReadResultFiles(const std::string& yaml_path, const std::string& h5_path) {
  FitResultFile r;
  ReadYaml(yaml_path, &r);
  std::string h5_run;
  try {
    ReadH5(h5_path, &r, &h5_run);
  } catch (const h5::Error& e) {
    throw ResultError(e.what());
  }
  const auto show = [](const std::string& id) { return id.empty() ? "none" : id; };
  if (h5_run != r.run_id) {
    throw ResultError(std::filesystem::path(yaml_path).parent_path().string() +
                      ": the files come from different fits: " +
                      std::filesystem::path(yaml_path).filename().string() + " is run " +
                      show(r.run_id) + ", " + std::filesystem::path(h5_path).filename().string() +
                      " is run " + show(h5_run) + " (run `sysid fit` again into this folder)");
  }
  return r;
}

FitResultFile ReadResult(const std::string& dir) {
  const std::filesystem::path d(dir);
  FitResultFile r = ReadResultFiles((d / "result.yaml").string(), (d / "result.h5").string());

  // one run: every identified model carries result.yaml's run id
  for (const auto& [model, file] : r.identified_models) {
    if (r.run_id.empty()) break;  // a result of an older version, or built by hand
    const std::string path = (d / file).string();
    std::ifstream in(path, std::ios::binary);
    if (!in) throw ResultError(path + ": missing (result.yaml lists it as model " + model + ")");
    std::string head(4096, '\0');
    in.read(head.data(), static_cast<std::streamsize>(head.size()));
    head.resize(static_cast<size_t>(in.gcount()));
    if (head.find(RunIdComment(r.run_id)) == std::string::npos) {
      throw ResultError(dir + ": the files come from different fits: " + file +
                        " is not from run " + r.run_id + " of result.yaml (run `sysid fit` " +
                        "again into this folder)");
    }
  }
  return r;
}

}  // namespace mjsysid::io
