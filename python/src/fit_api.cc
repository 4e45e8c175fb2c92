// mjsysid.fit(model, parameters, sequences, options=None, callback=None, measurements=None,
// control_delays=None, validation=None): the library API (sysid/problem.h) on Python data. The
// dicts are read into FitParameter / FitSequence / FitOptions / FitMeasurement / FitControlDelay;
// unknown keys and wrong shapes raise ValueError naming the key; everything else (names, bounds,
// shapes against the model, something to fit) is checked by Problem as for a C++ caller. A
// `measured` or `ctrl` with named columns (a pandas DataFrame, a dict) is matched to the model's
// sensors or actuators by name; a plain array is in model order. The model is a path, MJCF text, a
// mujoco.MjModel or a mujoco.MjSpec. Each sequence of the result gets its % fit per channel
// (channel_fits); held-out sequences (validation) are checked before the fit and simulated after
// it, as the runner does.
#include <nanobind/eigen/dense.h>
#include <nanobind/nanobind.h>
#include <nanobind/stl/map.h>
#include <nanobind/stl/string.h>
#include <nanobind/stl/vector.h>

#include <algorithm>
#include <cstdint>
#include <functional>
#include <limits>
#include <map>
#include <memory>
#include <stdexcept>
#include <string>
#include <tuple>
#include <utility>
#include <vector>

#include "bindings.h"
#include "core/mujoco_env.h"
#include "core/text.h"
#include "core/thread_pool.h"
#include "sysid/assess/metrics.h"
#include "sysid/fit/prepare.h"
#include "sysid/problem.h"
#include "sysid/run/fit_experiment.h"
#include "sysid/run/fit_table.h"
#include "sysid/run/multi_start.h"
#include "sysid/run/validation.h"

namespace mjsysid::python {
namespace {

using nb::arg;
using namespace nb::literals;

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

// "a, b, c"
std::string Joined(const std::vector<std::string>& names) {
  std::string out;
  for (const std::string& n : names) out += (out.empty() ? "" : ", ") + n;
  return out;
}

// The keys of the three kinds of dict, each list written once: CheckKeys, the docstring of
// fit() and the ValueError for an unknown key read it (tests/python/test_fit_options.py
// compares the options with docs/python.md).
// kParameterKeys: today's spellings and the experiment file's (target, bounds, transform), one of
// each pair per dict (ParameterOf)
const std::vector<std::string> kParameterKeys = {
    "name",  "kind",   "target", "object", "field", "index",     "initial", "lower",
    "upper", "bounds", "log",    "scale",  "prior", "transform", "models"};
const std::vector<std::string> kSequenceKeys = {
    "name", "model",   "ctrl",      "measured",  "qpos",       "qvel",        "act",
    "time", "sensors", "ctrl_time", "ctrl_hold", "ctrl_delay", "ctrl_before", "no_sensors"};
const std::vector<std::string> kOptionKeys = {"max_iterations",
                                              "function_tolerance",
                                              "gradient_tolerance",
                                              "parameter_tolerance",
                                              "threads",
                                              "loss",
                                              "loss_scale",
                                              "estimate_initial_state",
                                              "segment_steps",
                                              "continuity_weight",
                                              "continuity_scale",
                                              "jumping_sensors",
                                              "sensor_weights",
                                              "sensor_sigmas",
                                              "jacobian",
                                              "differences",
                                              "relative_step",
                                              "reduce_model",
                                              "gauss_newton_stop",
                                              "global_stage",
                                              "global_budget",
                                              "timestep_check",
                                              "subset_start",
                                              "states",
                                              "starts",
                                              "seed",
                                              "verbose"};
const std::vector<std::string> kMeasurementKeys = {"sensor", "delay", "gain", "bias"};
const std::vector<std::string> kTermKeys = {"initial", "fit", "lower", "upper"};
const std::vector<std::string> kControlDelayKeys = {"actuator", "initial", "lower", "upper"};

// the spellings of the experiment file's enums (docs/experiment-schema.md)
const std::vector<std::string> kDifferences = {"forward", "central"};
const std::vector<std::string> kContinuityScales = {"relative", "absolute"};
const std::vector<std::string> kJumpingSensors = {"omit", "fit"};
// in the order of Transform (sysid/types.h), as sysid/io/experiment_fit.cc spells them
const std::vector<std::string> kTransforms = {"none", "log", "scale"};

// the keys of `d` must be in `valid`; `what` names the dict in messages
void CheckKeys(const nb::dict& d, const std::vector<std::string>& valid, const std::string& what) {
  for (auto [key, value] : d) {
    const std::string k = nb::cast<std::string>(nb::str(key));
    if (std::find(valid.begin(), valid.end(), k) == valid.end()) {
      throw std::invalid_argument(what + ": unknown key '" + k + "'; valid: " + Joined(valid));
    }
  }
}

// d[key] converted to T, or `fallback` when absent; a wrong type names the key
template <typename T>
T Get(const nb::dict& d, const char* key, const T& fallback, const std::string& what) {
  if (!d.contains(key)) return fallback;
  try {
    return nb::cast<T>(d[key]);
  } catch (const nb::cast_error&) {
    throw std::invalid_argument(what + ": '" + key + "' has the wrong type (" +
                                nb::cast<std::string>(nb::str(nb::handle(d[key]).type())) + ")");
  }
}

// d[key] as the index of one of `names`, or `fallback` when absent; another string names the key
// and the valid spellings
int GetChoice(const nb::dict& d, const char* key, const std::vector<std::string>& names,
              int fallback, const std::string& what) {
  if (!d.contains(key)) return fallback;
  const std::string v = Get<std::string>(d, key, "", what);
  const auto it = std::find(names.begin(), names.end(), v);
  if (it == names.end()) {
    throw std::invalid_argument(what + ": " + key + " '" + v + "': expected " + Joined(names));
  }
  return static_cast<int>(it - names.begin());
}

// "(200, 2)": a numpy array's shape, for messages
std::string ShapeOf(const nb::object& a) {
  const nb::object shape = a.attr("shape");  // an object: nb::str of an accessor would cast it
  return nb::cast<std::string>(nb::str(shape));
}

// value as a float64 numpy array; a value numpy cannot convert names the key
nb::object FloatArray(nb::handle value, const char* key, const std::string& what) {
  nb::module_ np = nb::module_::import_("numpy");
  try {
    return np.attr("asarray")(value, "dtype"_a = "float64");
  } catch (nb::python_error& e) {
    throw std::invalid_argument(what + ": '" + key + "' is not an array of numbers (" +
                                nb::cast<std::string>(nb::str(value.type().attr("__name__"))) +
                                "): " + nb::cast<std::string>(nb::str(e.value())));
  }
}

// an array as a C-contiguous float64 matrix (a 1-D array is one column)
RowMatrix MatrixOf(nb::handle value, const char* key, const std::string& what) {
  nb::module_ np = nb::module_::import_("numpy");
  nb::object a = FloatArray(value, key, what);
  const int ndim = nb::cast<int>(a.attr("ndim"));
  if (ndim != 1 && ndim != 2) {
    throw std::invalid_argument(
        what + ": '" + key + "' must be a 1-D or 2-D array, got shape " + ShapeOf(a) + " (" +
        nb::cast<std::string>(nb::str(value.type().attr("__name__"))) + ")");
  }
  if (ndim == 1) a = a.attr("reshape")(-1, 1);
  return nb::cast<RowMatrix>(np.attr("ascontiguousarray")(a));
}

// d[key] as a float64 matrix (a 1-D array is one column), or 0 x 0 when absent
RowMatrix GetMatrix(const nb::dict& d, const char* key, const std::string& what) {
  if (!d.contains(key)) return RowMatrix();
  return MatrixOf(d[key], key, what);
}

// d[key] as a 1-D vector (empty when absent); scalar_ok: a number is one entry
Eigen::VectorXd GetVector(const nb::dict& d, const char* key, const std::string& what,
                          bool scalar_ok = false) {
  if (!d.contains(key)) return Eigen::VectorXd();
  nb::module_ np = nb::module_::import_("numpy");
  nb::object a = FloatArray(d[key], key, what);
  const int ndim = nb::cast<int>(a.attr("ndim"));
  if (ndim != 1 && !(scalar_ok && ndim == 0)) {
    throw std::invalid_argument(what + ": '" + key + "' must be " +
                                (scalar_ok ? "a number or a 1-D array" : "a 1-D array") +
                                ", got shape " + ShapeOf(a));
  }
  return nb::cast<Eigen::VectorXd>(np.attr("ascontiguousarray")(np.attr("ravel")(a)));
}

// The model objects whose columns a named `measured` (sensors) or `ctrl` (actuators) fills, in
// model order: each name, its columns' first index and count
struct Columns {
  const char* kind;     // "sensor" or "actuator"
  const char* article;  // "a" or "an"
  std::vector<std::string> names;
  std::vector<int> first, width;
  int total = 0;
};

Columns SensorColumns(const mjModel& m) {
  Columns c{"sensor", "a", {}, {}, {}, static_cast<int>(m.nsensordata)};
  for (int i = 0; i < m.nsensor; ++i) {
    const char* name = mj_id2name(&m, mjOBJ_SENSOR, i);
    c.names.push_back(name ? name : "");
    c.first.push_back(m.sensor_adr[i]);
    c.width.push_back(m.sensor_dim[i]);
  }
  return c;
}

Columns ActuatorColumns(const mjModel& m) {
  Columns c{"actuator", "an", {}, {}, {}, static_cast<int>(m.nu)};
  for (int i = 0; i < m.nu; ++i) {
    const char* name = mj_id2name(&m, mjOBJ_ACTUATOR, i);
    c.names.push_back(name ? name : "");
    c.first.push_back(i);
    c.width.push_back(1);
  }
  return c;
}

// a DataFrame's column labels as a Python list (list(df.columns): nb::list of the Index itself
// would not convert it)
nb::list ColumnLabels(nb::handle frame) {
  nb::module_ builtins = nb::module_::import_("builtins");
  return nb::cast<nb::list>(builtins.attr("list")(frame.attr("columns")));
}

// value with named columns: a dict, or a pandas DataFrame whose column labels are not pandas'
// default 0, 1, ... (a DataFrame made from an array without names, taken as that array)
bool HasNamedColumns(nb::handle value) {
  if (nb::isinstance<nb::dict>(value)) return true;
  if (!nb::hasattr(value, "columns") || !nb::hasattr(value, "to_numpy")) return false;
  const nb::list labels = ColumnLabels(value);
  for (size_t i = 0; i < nb::len(labels); ++i) {
    if (!nb::isinstance<nb::int_>(labels[i]) ||
        nb::cast<long long>(labels[i]) != static_cast<long long>(i)) {
      return true;
    }
  }
  return false;
}

// The named columns of `value` (a dict or a DataFrame, HasNamedColumns) placed by name into a
// T x cols.total matrix: "NAME" for a 1-D object (a dict's value may be T x width for a wider
// one) or "NAME[i]" for its column i. Objects in `required` must be given; the others, absent,
// are NaN (not measured). A label that names no object, or a missing required one, is a
// ValueError naming the labels given and the model's names.
RowMatrix NamedColumns(nb::handle value, const Columns& cols,
                       const std::vector<std::string>& required, const char* key,
                       const std::string& what, const std::string& model) {
  std::vector<std::pair<std::string, nb::object>> given;  // label, column(s)
  if (nb::isinstance<nb::dict>(value)) {
    for (auto [label, column] : nb::cast<nb::dict>(value)) {
      given.emplace_back(nb::cast<std::string>(nb::str(label)), nb::borrow(column));
    }
  } else {
    for (nb::handle label : ColumnLabels(value)) {
      given.emplace_back(nb::cast<std::string>(nb::str(label)), value.attr("__getitem__")(label));
    }
  }
  std::string labels, names;
  for (const auto& [label, column] : given) labels += (labels.empty() ? "" : ", ") + label;
  names = Joined(cols.names);
  const std::string lists = " (the columns given: " + labels + "; the " + cols.kind +
                            "s of model '" + model + "': " + names + ")";
  RowMatrix out;
  std::vector<bool> filled(cols.total, false);
  const std::string where = what + ": '" + key + "'";
  for (const auto& [label, column] : given) {
    // NAME or NAME[i]
    std::string name = label;
    int index = -1;
    const size_t open = label.rfind('[');
    if (open != std::string::npos && label.back() == ']' && open + 2 < label.size()) {
      const std::string digits = label.substr(open + 1, label.size() - open - 2);
      if (digits.find_first_not_of("0123456789") == std::string::npos) {
        name = label.substr(0, open);
        index = std::stoi(digits);
      }
    }
    auto it = std::find(cols.names.begin(), cols.names.end(), label);
    if (it != cols.names.end()) {
      index = -1;  // a name that itself ends in [i]
    } else {
      it = std::find(cols.names.begin(), cols.names.end(), name);
    }
    if (it == cols.names.end()) {
      throw std::invalid_argument(where + ": column '" + label + "' is not " + cols.article + " " +
                                  cols.kind + lists);
    }
    const size_t o = it - cols.names.begin();
    const int width = cols.width[o];
    if (index >= width) {
      throw std::invalid_argument(where + ": column '" + label + "': " + cols.kind + " '" + name +
                                  "' has " + std::to_string(width) + " column(s)" + lists);
    }
    const RowMatrix x = MatrixOf(column, key, what + ": '" + key + "' column '" + label + "'");
    const int expected = index >= 0 ? 1 : width;
    if (x.cols() != expected) {
      throw std::invalid_argument(
          where + ": column '" + label + "' must have " + std::to_string(expected) +
          " column(s), got " + std::to_string(x.cols()) +
          (index < 0 && width > 1
               ? " (give T x " + std::to_string(width) + ", or '" + name + "[0]' ... '" + name +
                     "[" + std::to_string(width - 1) + "]' one by one)"
               : ""));
    }
    if (out.size() == 0) out = RowMatrix::Constant(x.rows(), cols.total, kNaN);
    if (x.rows() != out.rows()) {
      throw std::invalid_argument(where + ": column '" + label + "' has " +
                                  std::to_string(x.rows()) + " rows, the columns before it " +
                                  std::to_string(out.rows()));
    }
    const int first = cols.first[o] + std::max(index, 0);
    for (int c = 0; c < expected; ++c) {
      if (filled[first + c]) {
        throw std::invalid_argument(where + ": column '" + label + "' gives a column of " +
                                    cols.kind + " '" + name + "' twice");
      }
      filled[first + c] = true;
      out.col(first + c) = x.col(c);
    }
  }
  std::vector<std::string> missing;
  for (size_t o = 0; o < cols.names.size(); ++o) {
    if (std::find(required.begin(), required.end(), cols.names[o]) == required.end()) continue;
    for (int c = 0; c < cols.width[o]; ++c) {
      if (filled[cols.first[o] + c]) continue;
      missing.push_back(cols.width[o] > 1 ? cols.names[o] + "[" + std::to_string(c) + "]"
                                          : cols.names[o]);
    }
  }
  if (!missing.empty()) {
    throw std::invalid_argument(where + ": no column for " + cols.kind + " " + Joined(missing) +
                                lists);
  }
  if (out.size() == 0) out = RowMatrix::Constant(0, cols.total, kNaN);
  return out;
}

// d has at most one of two spellings of one thing (today's and the experiment file's); a
// ValueError names both
void OneSpelling(const nb::dict& d, const std::vector<const char*>& ours, const char* yaml,
                 const std::string& what) {
  if (!d.contains(yaml)) return;
  for (const char* key : ours) {
    if (!d.contains(key)) continue;
    std::string both;
    for (const char* k : ours) both += std::string(both.empty() ? "'" : "/'") + k + "'";
    throw std::invalid_argument(what + ": '" + key + "' and '" + yaml +
                                "' are two spellings of one thing (" + both +
                                " here, the experiment file's '" + yaml + "'): give one");
  }
}

// d[key] as [a, b] or {names[0]: a, names[1]: b} (the experiment file's map); `what` names d
std::pair<double, double> GetPair(const nb::dict& d, const char* key,
                                  const std::pair<const char*, const char*>& names,
                                  const std::string& what) {
  const std::string expected = std::string("'") + key + "' is [" + names.first + ", " +
                               names.second + "] or {" + names.first + ": .., " + names.second +
                               ": ..}";
  if (nb::isinstance<nb::dict>(d[key])) {
    const nb::dict m = nb::cast<nb::dict>(d[key]);
    const std::string w = what + "." + key;
    CheckKeys(m, {names.first, names.second}, w);
    if (!m.contains(names.first) || !m.contains(names.second)) {
      throw std::invalid_argument(what + ": " + expected);
    }
    return {Get<double>(m, names.first, 0, w), Get<double>(m, names.second, 0, w)};
  }
  const auto v = Get<std::vector<double>>(d, key, {}, what);
  if (v.size() != 2) throw std::invalid_argument(what + ": " + expected);
  return {v[0], v[1]};
}

// The parameter's keys are today's (kind, lower/upper, log: true, scale alone) or the experiment
// file's (target, bounds: [lower, upper], transform: none | log | scale with scale); both
// spellings of one thing in one dict are a ValueError. initial: a number or "auto" (the
// equation-error start of Problem::Fit, FitParameter::initial_auto, as `initial: auto`).
FitParameter ParameterOf(const nb::dict& d, size_t i) {
  const std::string what = "parameters[" + std::to_string(i) + "]";
  CheckKeys(d, kParameterKeys, what);
  OneSpelling(d, {"kind"}, "target", what);
  OneSpelling(d, {"lower", "upper"}, "bounds", what);
  OneSpelling(d, {"log"}, "transform", what);
  for (const char* key : {"name", "initial"}) {
    if (!d.contains(key)) throw std::invalid_argument(what + ": '" + key + "' is required");
  }
  if (!d.contains("kind") && !d.contains("target")) {
    throw std::invalid_argument(what + ": 'target' (or 'kind') is required");
  }
  FitParameter p;
  p.name = Get<std::string>(d, "name", "", what);
  p.target.kind = Get<std::string>(d, d.contains("target") ? "target" : "kind", "", what);
  p.target.object = Get<std::string>(d, "object", "", what);
  p.target.field = Get<std::string>(d, "field", "", what);
  p.target.index = Get<int>(d, "index", 0, what);
  if (nb::isinstance<nb::str>(d["initial"])) {
    if (nb::cast<std::string>(d["initial"]) != "auto") {
      throw std::invalid_argument(what + ": 'initial' is a number or 'auto', got '" +
                                  nb::cast<std::string>(d["initial"]) + "'");
    }
    // decided by the fit (the equation-error start); NaN until then, as from the experiment file
    p.initial_auto = true;
    p.initial = kNaN;
  } else {
    p.initial = Get<double>(d, "initial", 0, what);
  }
  p.lower = Get<double>(d, "lower", p.lower, what);
  p.upper = Get<double>(d, "upper", p.upper, what);
  if (d.contains("bounds")) {
    std::tie(p.lower, p.upper) = GetPair(d, "bounds", {"lower", "upper"}, what);
  }
  if (Get<bool>(d, "log", false, what)) p.transform = Transform::kLog;
  if (d.contains("transform")) {
    p.transform = static_cast<Transform>(GetChoice(d, "transform", kTransforms, 0, what));
    // as in the experiment file: scale is the factor of transform: scale, ignored otherwise
    p.scale = Get<double>(d, "scale", p.scale, what);
  } else if (d.contains("scale")) {
    p.transform = Transform::kScale;
    p.scale = Get<double>(d, "scale", 1, what);
  }
  if (d.contains("prior")) {
    const auto [mean, sigma] = GetPair(d, "prior", {"mean", "sigma"}, what);
    p.Prior(mean, sigma);
  }
  p.models = Get<std::vector<std::string>>(d, "models", {}, what);
  return p;
}

// one term of a measurement: {initial?, fit?, lower?, upper?}, defaults those of `term`
void TermOf(const nb::dict& d, const char* key, const std::string& what,
            FitMeasurement::Term* term) {
  if (!d.contains(key)) return;
  const std::string w = what + "." + key;
  if (!nb::isinstance<nb::dict>(d[key])) throw std::invalid_argument(w + ": expected a dict");
  const nb::dict t = nb::cast<nb::dict>(d[key]);
  CheckKeys(t, kTermKeys, w);
  term->initial = Get<double>(t, "initial", term->initial, w);
  term->fit = Get<bool>(t, "fit", term->fit, w);
  term->lower = Get<double>(t, "lower", term->lower, w);
  term->upper = Get<double>(t, "upper", term->upper, w);
}

// measured = gain * simulated(t - delay) + bias for one sensor (the experiment's `measurement:`)
FitMeasurement MeasurementOf(const nb::dict& d, size_t i) {
  const std::string what = "measurements[" + std::to_string(i) + "]";
  CheckKeys(d, kMeasurementKeys, what);
  if (!d.contains("sensor")) throw std::invalid_argument(what + ": 'sensor' is required");
  FitMeasurement m;
  m.sensor = Get<std::string>(d, "sensor", "", what);
  TermOf(d, "delay", what, &m.delay);
  TermOf(d, "gain", what, &m.gain);
  TermOf(d, "bias", what, &m.bias);
  return m;
}

// a transport delay of the controls fitted as a variable (the experiment's controls.delay with
// fit: true): one actuator's, or shared by every actuator without its own (actuator absent)
FitControlDelay ControlDelayOf(const nb::dict& d, size_t i) {
  const std::string what = "control_delays[" + std::to_string(i) + "]";
  CheckKeys(d, kControlDelayKeys, what);
  FitControlDelay c;
  c.actuator = Get<std::string>(d, "actuator", "", what);
  c.initial = Get<double>(d, "initial", c.initial, what);
  c.lower = Get<double>(d, "lower", c.lower, what);
  c.upper = Get<double>(d, "upper", c.upper, what);
  return c;
}

// models: the names given to Problem::AddModel (a sequence names one with `model` when there are
// several), in order, and their models (`measured` and `ctrl` with named columns are placed by
// the model's sensor and actuator names)
FitSequence SequenceOf(const nb::dict& d, size_t i, const std::vector<std::string>& models,
                       const std::vector<const mjModel*>& compiled,
                       const std::string& list = "sequences") {
  const std::string what = list + "[" + std::to_string(i) + "]";
  CheckKeys(d, kSequenceKeys, what);
  for (const char* key : {"ctrl", "measured"}) {
    if (!d.contains(key)) throw std::invalid_argument(what + ": '" + key + "' is required");
  }
  FitSequence s;
  s.name = Get<std::string>(d, "name", "seq" + std::to_string(i), what);
  if (models.size() > 1 && !d.contains("model")) {
    throw std::invalid_argument(what + ": 'model' is required with several models (one of " +
                                Joined(models) + ")");
  }
  s.model = Get<std::string>(d, "model", models.front(), what);
  const auto model = std::find(models.begin(), models.end(), s.model);
  if (model == models.end()) {
    throw std::invalid_argument(what + ": model '" + s.model + "' is not one of " + Joined(models));
  }
  const mjModel& m = *compiled[model - models.begin()];
  s.no_sensors = Get<bool>(d, "no_sensors", false, what);
  s.sensors = Get<std::vector<std::string>>(d, "sensors", {}, what);
  // columns by name (a DataFrame, a dict): every actuator's; every fitted sensor's (`sensors`,
  // default all; none with no_sensors), the others NaN when absent
  if (HasNamedColumns(d["ctrl"])) {
    const Columns actuators = ActuatorColumns(m);
    s.ctrl = NamedColumns(d["ctrl"], actuators, actuators.names, "ctrl", what, s.model);
  } else {
    s.ctrl = GetMatrix(d, "ctrl", what);
  }
  if (HasNamedColumns(d["measured"])) {
    const Columns sensors = SensorColumns(m);
    const std::vector<std::string> required = s.no_sensors        ? std::vector<std::string>()
                                              : s.sensors.empty() ? sensors.names
                                                                  : s.sensors;
    s.measured = NamedColumns(d["measured"], sensors, required, "measured", what, s.model);
  } else {
    s.measured = GetMatrix(d, "measured", what);
  }
  // qpos, qvel, act: the initial state (1-D), or the logged states (T rows: fitted where
  // options' `states` says so, and their first row the initial state)
  const std::pair<const char*, std::pair<Eigen::VectorXd*, RowMatrix*>> states[] = {
      {"qpos", {&s.x0.qpos, &s.qpos}},
      {"qvel", {&s.x0.qvel, &s.qvel}},
      {"act", {&s.x0.act, &s.act}}};
  for (const auto& [key, into] : states) {
    if (!d.contains(key)) continue;
    if (nb::cast<int>(FloatArray(d[key], key, what).attr("ndim")) == 2) {
      *into.second = GetMatrix(d, key, what);
      if (into.second->rows() > 0) *into.first = into.second->row(0).transpose();
    } else {
      *into.first = GetVector(d, key, what, /*scalar_ok=*/true);
    }
  }
  s.time = GetVector(d, "time", what);
  if (s.time.size() > 0) s.x0.time = s.time[0];
  // the controls' own clock and how they reach the steps (the experiment's `controls:`)
  s.ctrl_time = GetVector(d, "ctrl_time", what);
  if (d.contains("ctrl_hold")) {
    // one spelling for every actuator, or a list with one per actuator
    std::vector<std::string> holds;
    if (nb::isinstance<nb::str>(d["ctrl_hold"])) {
      holds.assign(s.ctrl.cols(), Get<std::string>(d, "ctrl_hold", "", what));
    } else {
      holds = Get<std::vector<std::string>>(d, "ctrl_hold", {}, what);
    }
    for (const std::string& h : holds) {
      if (h == ControlHoldName(ControlHold::kZeroOrder)) {
        s.ctrl_hold.push_back(ControlHold::kZeroOrder);
      } else if (h == ControlHoldName(ControlHold::kLinear)) {
        s.ctrl_hold.push_back(ControlHold::kLinear);
      } else {
        throw std::invalid_argument(what + ": ctrl_hold '" + h + "': expected " +
                                    ControlHoldName(ControlHold::kZeroOrder) + " or " +
                                    ControlHoldName(ControlHold::kLinear));
      }
    }
  }
  if (d.contains("ctrl_delay")) {
    // one delay (s) for every actuator, or one per actuator
    const Eigen::VectorXd delay = GetVector(d, "ctrl_delay", what, /*scalar_ok=*/true);
    if (delay.size() == 1) {
      s.ctrl_delay.assign(s.ctrl.cols(), delay[0]);
    } else {
      s.ctrl_delay.assign(delay.data(), delay.data() + delay.size());
    }
  }
  if (d.contains("ctrl_before")) {
    // every actuator's control before its first logged one: the first held, or 0
    const std::string b = Get<std::string>(d, "ctrl_before", "", what);
    if (b == ControlBeforeName(ControlBefore::kHold)) {
      s.ctrl_before = ControlBefore::kHold;
    } else if (b == ControlBeforeName(ControlBefore::kZero)) {
      s.ctrl_before = ControlBefore::kZero;
    } else {
      throw std::invalid_argument(what + ": ctrl_before '" + b + "': expected " +
                                  ControlBeforeName(ControlBefore::kHold) + " or " +
                                  ControlBeforeName(ControlBefore::kZero));
    }
  }
  return s;
}

// How many fits from different starts, and the seed that draws them (the experiment's
// solver.starts and solver.seed; sysid/run/multi_start.h)
struct Starts {
  int count = 1;
  std::uint64_t seed = 0;
};

FitOptions OptionsOf(const nb::dict& d, Starts* starts) {
  const std::string what = "options";
  CheckKeys(d, kOptionKeys, what);
  FitOptions o;
  // the experiment file's ranges: starts 1..10000, seed >= 0
  starts->count = Get<int>(d, "starts", 1, what);
  if (starts->count < 1 || starts->count > 10000) {
    throw std::invalid_argument("options: starts must be 1..10000, got " +
                                std::to_string(starts->count));
  }
  const long long seed = Get<long long>(d, "seed", 0, what);
  if (seed < 0) {
    throw std::invalid_argument("options: seed must be >= 0, got " + std::to_string(seed));
  }
  starts->seed = static_cast<std::uint64_t>(seed);
  o.max_iterations = Get<int>(d, "max_iterations", o.max_iterations, what);
  o.function_tolerance = Get<double>(d, "function_tolerance", o.function_tolerance, what);
  o.gradient_tolerance = Get<double>(d, "gradient_tolerance", o.gradient_tolerance, what);
  o.parameter_tolerance = Get<double>(d, "parameter_tolerance", o.parameter_tolerance, what);
  // Ceres refuses these at the solve (status solver_failed); the experiment file's rules, except
  // that 0 iterations (the start evaluated) stays allowed as before
  if (o.max_iterations < 0) {
    throw std::invalid_argument("options: max_iterations must be >= 0, got " +
                                std::to_string(o.max_iterations));
  }
  const std::pair<const char*, double> tolerances[] = {
      {"function_tolerance", o.function_tolerance},
      {"gradient_tolerance", o.gradient_tolerance},
      {"parameter_tolerance", o.parameter_tolerance}};
  for (const auto& [name, value] : tolerances) {
    if (!(value >= 0)) {
      throw std::invalid_argument(std::string("options: ") + name + " must be >= 0, got " +
                                  FormatDigits(value, 6));
    }
  }
  o.threads = CheckedThreads(Get<int>(d, "threads", o.threads, what), what + "['threads']");
  const LossType loss_types[] = {LossType::kNone, LossType::kHuber, LossType::kCauchy};
  std::vector<std::string> losses;
  for (LossType t : loss_types) losses.push_back(LossTypeName(t));
  if (d.contains("loss")) o.loss = loss_types[GetChoice(d, "loss", losses, 0, what)];
  o.loss_scale = Get<double>(d, "loss_scale", o.loss_scale, what);
  o.estimate_initial_state = Get<bool>(d, "estimate_initial_state", false, what);
  o.segment_steps = Get<int>(d, "segment_steps", o.segment_steps, what);
  o.continuity_weight = Get<double>(d, "continuity_weight", o.continuity_weight, what);
  o.continuity_relative =
      GetChoice(d, "continuity_scale", kContinuityScales, o.continuity_relative ? 0 : 1, what) == 0;
  o.fit_jumping_sensors =
      GetChoice(d, "jumping_sensors", kJumpingSensors, o.fit_jumping_sensors ? 1 : 0, what) == 1;
  o.sensor_weights = Get<std::map<std::string, double>>(d, "sensor_weights", {}, what);
  // a sigma is a weight 1/sigma that also enters the model_mismatch verdict (as in YAML); "auto":
  // estimated from the log at the fit's start (sigma: auto)
  for (const auto& [sensor, value] :
       Get<std::map<std::string, nb::object>>(d, "sensor_sigmas", {}, what)) {
    if (nb::isinstance<nb::str>(value) && nb::cast<std::string>(value) == "auto") {
      o.sensors_sigma_from_log.push_back(sensor);
      continue;
    }
    double sigma = 0;
    try {
      sigma = nb::cast<double>(value);
    } catch (const nb::cast_error&) {
      throw std::invalid_argument("options: sensor_sigmas['" + sensor +
                                  "'] must be a number > 0 or 'auto'");
    }
    if (!(sigma > 0)) {
      throw std::invalid_argument("options: sensor_sigmas['" + sensor + "'] must be > 0");
    }
    o.sensor_weights[sensor] = 1.0 / sigma;
    o.sensors_with_sigma.push_back(sensor);
  }
  // the Jacobian (the experiment's solver.jacobian, differences, relative_step)
  const JacobianMode jacobian_modes[] = {JacobianMode::kAuto, JacobianMode::kDirectional,
                                         JacobianMode::kMatrix, JacobianMode::kWholeRollout};
  std::vector<std::string> modes;
  for (JacobianMode m : jacobian_modes) modes.push_back(JacobianModeName(m));
  if (d.contains("jacobian")) {
    o.jacobian.mode = jacobian_modes[GetChoice(d, "jacobian", modes, 0, what)];
  }
  o.jacobian.central = GetChoice(d, "differences", kDifferences, o.jacobian.central, what) == 1;
  o.jacobian.relative_step = Get<double>(d, "relative_step", o.jacobian.relative_step, what);
  if (!(o.jacobian.relative_step > 0)) {
    throw std::invalid_argument("options: relative_step must be > 0");
  }
  o.reduce_model = Get<bool>(d, "reduce_model", o.reduce_model, what);
  o.gauss_newton_stop = Get<double>(d, "gauss_newton_stop", o.gauss_newton_stop, what);
  // the global stage (sysid/fit/global_stage.h)
  o.global_stage = Get<bool>(d, "global_stage", o.global_stage, what);
  o.global_budget = Get<double>(d, "global_budget", o.global_budget, what);
  if (!(o.global_budget > 0)) throw std::invalid_argument("options: global_budget must be > 0");
  // the timestep check (sysid/fit/timestep_check.h)
  o.timestep_check = Get<bool>(d, "timestep_check", o.timestep_check, what);
  // the subset start (sysid/fit/subset_start.h)
  o.subset_start = Get<bool>(d, "subset_start", o.subset_start, what);
  // logged states fitted as data: {qpos: {sigma, joints?}, qvel: ..., act: {sigma, actuators?}}
  if (d.contains("states")) {
    if (!nb::isinstance<nb::dict>(d["states"])) {
      throw std::invalid_argument("options: states: expected a dict");
    }
    const nb::dict st = nb::cast<nb::dict>(d["states"]);
    CheckKeys(st, {"qpos", "qvel", "act"}, "options.states");
    FitStates::Part* parts[] = {&o.states.qpos, &o.states.qvel, &o.states.act};
    const char* names[] = {"qpos", "qvel", "act"};
    for (int i = 0; i < 3; ++i) {
      if (!st.contains(names[i])) continue;
      const std::string w = std::string("options.states.") + names[i];
      if (!nb::isinstance<nb::dict>(st[names[i]]))
        throw std::invalid_argument(w + ": expected a dict");
      const nb::dict part = nb::cast<nb::dict>(st[names[i]]);
      const char* objects = i < 2 ? "joints" : "actuators";
      CheckKeys(part, {"sigma", objects}, w);
      if (!part.contains("sigma")) throw std::invalid_argument(w + ": 'sigma' is required");
      const Eigen::VectorXd sigma = GetVector(part, "sigma", w, /*scalar_ok=*/true);
      parts[i]->fit = true;
      parts[i]->sigma.assign(sigma.data(), sigma.data() + sigma.size());
      parts[i]->names = Get<std::vector<std::string>>(part, objects, {}, w);
    }
  }
  o.verbose = Get<bool>(d, "verbose", false, what);
  return o;
}

// each item of `list` (None: no item) as a dict, with its index; `what` names the list in errors
void ForEachDict(const nb::object& list, const char* what,
                 const std::function<void(const nb::dict&, size_t)>& each) {
  if (list.is_none()) return;
  if (!nb::isinstance<nb::list>(list)) {
    throw std::invalid_argument(std::string(what) + ": expected a list of dicts");
  }
  const nb::list items = nb::cast<nb::list>(list);
  for (size_t i = 0; i < nb::len(items); ++i) {
    if (!nb::isinstance<nb::dict>(items[i])) {
      throw std::invalid_argument(std::string(what) + "[" + std::to_string(i) +
                                  "]: expected a dict");
    }
    each(nb::cast<nb::dict>(items[i]), i);
  }
}

}  // namespace

namespace {

// A mujoco.MjModel (or a mujoco.MjSpec, compiled first) as a model of this library: through its
// MJB bytes (mj_saveModel), which libmujoco loads with its own version check: a wheel's model
// whose layout differs is refused rather than misread. `what` names the argument in errors.
ModelPtr ModelOfMujoco(nb::handle model, const std::string& what) {
  nb::module_ mujoco = nb::module_::import_("mujoco");
  nb::module_ np = nb::module_::import_("numpy");
  nb::object compiled = nb::borrow(model);
  if (nb::isinstance(model, mujoco.attr("MjSpec"))) {
    try {
      compiled = model.attr("compile")();
    } catch (nb::python_error& e) {
      throw ModelLoadError(
          what + ": the MjSpec does not compile: " + nb::cast<std::string>(nb::str(e.value())));
    }
  }
  const long long size = nb::cast<long long>(mujoco.attr("mj_sizeModel")(compiled));
  nb::object buffer = np.attr("zeros")(size, "dtype"_a = "uint8");
  mujoco.attr("mj_saveModel")(compiled, nb::none(), buffer);
  const nb::bytes bytes = nb::cast<nb::bytes>(buffer.attr("tobytes")());
  InstallMujocoHandlers();
  mjModel* m = nullptr;
  try {
    m = mj_loadModelBuffer(bytes.c_str(), static_cast<mjtSize>(bytes.size()));
  } catch (const MujocoError& e) {
    throw ModelLoadError(what + ": the MjModel cannot be loaded: " + e.what());
  }
  if (m == nullptr) {
    throw ModelLoadError(what + ": the MjModel cannot be loaded (mujoco " +
                         nb::cast<std::string>(mujoco.attr("__version__")) + ", this module's " +
                         MujocoVersion() + ")");
  }
  return ModelPtr(m);
}

// a mujoco.MjModel or mujoco.MjSpec (the mujoco module already imported: such an object exists)
bool IsMujocoModel(nb::handle model) {
  nb::module_ sys = nb::module_::import_("sys");
  nb::object mujoco = sys.attr("modules").attr("get")("mujoco");
  if (mujoco.is_none()) return false;
  return nb::isinstance(model, mujoco.attr("MjModel")) ||
         (nb::hasattr(mujoco, "MjSpec") && nb::isinstance(model, mujoco.attr("MjSpec")));
}

}  // namespace

ModelPtr ModelOf(nb::handle model, const std::string& what) {
  if (IsMujocoModel(model)) return ModelOfMujoco(model, what);
  if (!nb::isinstance<nb::str>(model) && !nb::hasattr(model, "__fspath__")) {
    throw std::invalid_argument(what + ": expected a path, MJCF text, a mujoco.MjModel or a " +
                                "mujoco.MjSpec, got " +
                                nb::cast<std::string>(nb::str(model.type().attr("__name__"))));
  }
  const std::string text = nb::cast<std::string>(nb::str(model));
  const size_t first = text.find_first_not_of(" \t\r\n");
  if (first != std::string::npos && text[first] == '<') return LoadModelFromString(text);
  return LoadModel(text);
}

namespace {

FitResult Fit(nb::object model, nb::object parameters, nb::object sequences, nb::object options,
              nb::object callback, nb::object measurements, nb::object control_delays,
              nb::object validation) {
  // one model (named "model"), or several: {name: model}
  Problem problem;
  std::vector<std::string> models;
  std::vector<ModelPtr> compiled;  // as given to AddModel, for the sequences' named columns
  if (nb::isinstance<nb::dict>(model)) {
    for (auto [name, value] : nb::cast<nb::dict>(model)) {
      models.push_back(nb::cast<std::string>(nb::str(name)));
      compiled.push_back(ModelOf(value, "model['" + models.back() + "']"));
      problem.AddModel(models.back(), *compiled.back());
    }
    if (models.empty()) throw std::invalid_argument("model: an empty dict");
  } else {
    models.push_back("model");
    compiled.push_back(ModelOf(model, "model"));
    problem.AddModel("model", *compiled.back());
  }
  std::vector<const mjModel*> by_index;
  for (const ModelPtr& m : compiled) by_index.push_back(m.get());
  // what is added to the problem, kept for the starts of a multi-start fit (each start a Problem
  // of its own: run::ProblemFrom)
  run::BuiltProblem added;
  ForEachDict(parameters, "parameters", [&](const nb::dict& d, size_t i) {
    added.parameters.push_back(ParameterOf(d, i));
    problem.AddParameter(added.parameters.back());
  });
  ForEachDict(measurements, "measurements", [&](const nb::dict& d, size_t i) {
    added.measurements.push_back(MeasurementOf(d, i));
    problem.AddMeasurement(added.measurements.back());
  });
  ForEachDict(control_delays, "control_delays", [&](const nb::dict& d, size_t i) {
    added.control_delays.push_back(ControlDelayOf(d, i));
    problem.AddControlDelay(added.control_delays.back());
  });
  ForEachDict(sequences, "sequences", [&](const nb::dict& d, size_t i) {
    added.sequences.push_back(SequenceOf(d, i, models, by_index));
    problem.AddSequence(added.sequences.back());
  });
  // held-out sequences (as the experiment's `validation:`): checked now as a fitted sequence is,
  // simulated at the start and at the estimate after the fit (sysid/run/validation.h)
  std::vector<FitSequence> held_out;
  ForEachDict(validation, "validation", [&](const nb::dict& d, size_t i) {
    held_out.push_back(SequenceOf(d, i, models, by_index, "validation"));
    const FitSequence& sq = held_out.back();
    const auto mi = std::find(models.begin(), models.end(), sq.model) - models.begin();
    CheckHeldOutSequence(sq, *by_index[static_cast<size_t>(mi)],
                         "validation[" + std::to_string(i) + "] ('" + sq.name + "'): ");
  });
  FitOptions fit_options;
  Starts starts;
  if (!options.is_none()) {
    if (!nb::isinstance<nb::dict>(options)) throw std::invalid_argument("options: expected a dict");
    fit_options = OptionsOf(nb::cast<nb::dict>(options), &starts);
  }
  added.model_names = models;
  added.models = std::move(compiled);
  FitGuard guard(std::move(callback));
  fit_options.interrupt = guard.interrupt();
  fit_options.on_iteration = guard.OnIteration(nullptr);
  // options["verbose"]: the progress table on stderr (sysid/run/fit_table.h)
  run::FitTable table(WriteStderrLine, false);
  if (fit_options.verbose) fit_options.observer = &table;
  FitResult result;
  {
    nb::gil_scoped_release release;
    if (starts.count > 1) {
      // the runner's multi-start (sysid/run/multi_start.h): min(starts, threads) fits at a time,
      // every thread counted (0: all cores), one line per finished start with verbose
      FitOptions multi = fit_options;
      multi.threads = ThreadCount(fit_options.threads);
      result = run::FitFromStarts(added, multi, starts.count, starts.seed, fit_options.verbose);
    } else {
      result = problem.Fit(fit_options);
    }
    // each sequence's % fit and NRMSE per channel, as the runner gives them
    for (SequenceResult& sr : result.sequences) sr.channel_fits = ChannelFits(sr);
    for (FitSequence& sq : held_out) {
      const auto mi = std::find(models.begin(), models.end(), sq.model) - models.begin();
      const mjModel& m = *by_index[static_cast<size_t>(mi)];
      run::ApplyFittedControlDelays(m, added.control_delays, result.parameters, &sq);
      result.validation.push_back(
          run::SimulateHeldOut(m, added.parameters, added.measurements, result.parameters, sq,
                               ThreadCount(fit_options.threads), &result.warnings));
    }
  }
  table.Flush();
  guard.RaiseCallbackError();
  return result;
}

}  // namespace

void BindFitApi(nb::module_& m) {
  // the docstring names the keys of the tables above (it lives as long as the module)
  static const std::string doc =
      "Fits a model's parameters to logged sequences (sysid/problem.h; docs/python.md).\n\n"
      "model: an MJCF path, MJCF text, a mujoco.MjModel or a mujoco.MjSpec, or a dict {name: "
      "model} of several models (each "
      "sequence names its `model`, a parameter the `models` it applies to; default all). "
      "parameters: list of dicts {" +
      Joined(kParameterKeys) +
      "} (name, target, initial required; object | field; the experiment file's names target, "
      "bounds: [lower, upper], transform: none|log|scale, prior: {mean, sigma}, or kind, lower, "
      "upper, log: True, prior: [mean, sigma], one spelling of each; initial a number or 'auto', "
      "the equation-error start from the logged qpos and qvel). " +
      "sequences: list of dicts {" + Joined(kSequenceKeys) +
      "} (ctrl T x nu and measured T x nsensordata required: arrays in model order, or a "
      "DataFrame or dict whose columns are matched to the actuators and sensors by name; qpos, "
      "qvel, act: "
      "the initial state, or T rows of logged states). options: dict {" +
      Joined(kOptionKeys) +
      "} (starts > 1: the experiment runner's multi-start from starts spread by seed; the "
      "callback is then not called). callback(IterationInfo) after every successful iteration. "
      "measurements: list of "
      "dicts {" +
      Joined(kMeasurementKeys) + "}, each term a dict {" + Joined(kTermKeys) +
      "}: measured = gain * simulated(t - delay) + bias, fitted terms estimated as "
      "SENSOR.delay, SENSOR.gain, SENSOR.bias. control_delays: list of dicts {" +
      Joined(kControlDelayKeys) +
      "} (s; no actuator: shared by every actuator without its own), estimated as "
      "controls.delay[.ACTUATOR]. validation: list of dicts as `sequences`, held out (the "
      "experiment's validation:): never fitted, checked before the fit, simulated from their "
      "logged initial state at the start and at the estimate into FitResult.validation, each with "
      "its channel_fits."
      " The GIL is released during "
      "the fit; Ctrl-C stops it after the current iteration (status interrupted). Returns a "
      "FitResult (to_dict(): result.yaml's names; to_pandas(): the parameters' table).";
  m.def("fit", &Fit, arg("model"), arg("parameters"), arg("sequences"), arg("options") = nb::none(),
        arg("callback") = nb::none(), arg("measurements") = nb::none(),
        arg("control_delays") = nb::none(), arg("validation") = nb::none(), doc.c_str());
}

}  // namespace mjsysid::python
