#include "sysid/io/experiment.h"

#include <yaml-cpp/yaml.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <limits>
#include <sstream>
#include <utility>

#include "core/text.h"
#include "sysid/io/yaml_reader.h"

namespace mjsysid::io {
namespace {

namespace fs = std::filesystem;

// The experiment schema (docs/experiment-schema.md) on top of the YAML reader.
class Parser : public YamlReader {
 public:
  // file: as named in marks; base_dir: for relative paths; default_name: when `name` is absent
  Parser(std::string file, fs::path base_dir, std::string default_name)
      : YamlReader(std::move(file), std::move(base_dir)), default_name_(std::move(default_name)) {}

  ExperimentConfig Parse(const YAML::Node& root);

 private:
  // a map of arbitrary names to finite numbers, in file order
  std::vector<NamedValue> NamedValues(const Field& f) const;
  void ParseModels(const MapReader& root, ExperimentConfig* c) const;
  void ParseData(const Field& f, ExperimentConfig* c) const;
  // `sequences:` (into c->sequences) or `validation:` (into c->validation): "seq" or "model/seq"
  void ParseSequences(const Field& f, ExperimentConfig* c,
                      std::vector<SequenceRef> ExperimentConfig::*into) const;
  void ParseSensors(const Field& f, ExperimentConfig* c) const;
  ParameterSpec ParseParameter(const Field& f, const ExperimentConfig& c) const;
  MeasurementSpec ParseMeasurement(const Field& f, const ExperimentConfig& c) const;
  void ParseTerm(const Field& f, bool is_delay, FitMeasurement::Term* term, Marks* marks) const;
  void ParseControls(const Field& f, ExperimentConfig* c) const;
  void ParseSolver(const Field& f, ExperimentConfig* c) const;
  void ParseStates(const Field& f, ExperimentConfig* c) const;
  void ParseSimulate(const Field& f, const ExperimentConfig& c, SimulateOptions* s) const;
  Excitation ParseExcitation(const Field& f, bool needs_actuator) const;

  std::string default_name_;
};

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
    "solver",      "simulate", "output",     "validation",  "controls",      "states"};
const std::vector<std::string> kParameterKeys = {"name",  "target",  "object", "field",
                                                 "index", "initial", "bounds", "transform",
                                                 "scale", "prior",   "models"};
const std::vector<std::string> kSensorTimes = {"pre", "post"};
// in the order of ControlHold
const std::vector<std::string> kControlHolds = {"zoh", "linear"};
const std::vector<std::string> kTransforms = {"none", "log", "scale"};
// in the order of core's JacobianMode
const std::vector<std::string> kJacobianModes = {"auto", "directional", "matrix", "whole_rollout"};
const std::vector<std::string> kDifferences = {"forward", "central"};
const std::vector<std::string> kLossTypes = {"none", "huber", "cauchy"};
const std::vector<std::string> kExcitationTypes = {"sines", "chirp", "prbs", "zero"};

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
  if (r.Has("sequences")) ParseSequences(r.Get("sequences"), &c, &ExperimentConfig::sequences);
  if (r.Has("validation")) {
    ParseSequences(r.Get("validation"), &c, &ExperimentConfig::validation);
    // a sequence is fitted or held out, never both
    for (const SequenceRef& v : c.validation) {
      for (const SequenceRef& q : c.sequences) {
        if (q.name == v.name && (q.model.empty() || v.model.empty() || q.model == v.model)) {
          Fail(v.mark,
               "validation: sequence " + Quote(v.name) + " is also fitted (`sequences:` at line " +
                   std::to_string(q.mark.line) + ")",
               "a validation sequence is held out of the fit: remove it from one of the lists");
        }
      }
    }
  }
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

  if (r.Has("controls")) ParseControls(r.Get("controls"), &c);

  // something must be fitted
  bool fits_measurement = false;
  for (const MeasurementSpec& ms : c.measurement) {
    fits_measurement |= ms.delay.fit || ms.gain.fit || ms.bias.fit;
  }
  for (const ExperimentConfig::ControlDelaySpec& cd : c.control_delays) {
    fits_measurement |= cd.term.fit;
  }
  if (c.parameters.empty() && !fits_measurement) {
    Fail(r.Has("parameters") ? r.Get("parameters").mark : c.marks.self, "no parameters to identify",
         "add a 'parameters' list, or set 'fit: true' on a measurement delay, gain or bias");
  }

  if (r.Has("initial_state")) {
    const MapReader s(*this, r.Get("initial_state"), {"estimate"});
    if (s.Has("estimate")) c.options.estimate_initial_state = Bool(s.Get("estimate"));
  }
  // multiple_shooting: auto (also when absent), or {segment_steps: auto|0|N, continuity_weight}
  auto segment_steps = [&](const Field& f) {
    if (f.node.IsScalar() && f.node.Scalar() == "auto") return -1;
    return static_cast<int>(Integer(f, 0, std::numeric_limits<int>::max()));
  };
  if (r.Has("multiple_shooting") && r.Get("multiple_shooting").node.IsScalar()) {
    const Field f = r.Get("multiple_shooting");
    if (f.node.Scalar() != "auto") {
      Fail(f.mark, f.path + ": expected 'auto' or a map, got " + Quote(f.node.Scalar()),
           "multiple_shooting: auto, or {segment_steps: auto|0|N, continuity_weight: w}");
    }
    c.options.segment_steps = -1;
  } else if (r.Has("multiple_shooting")) {
    const MapReader s(*this, r.Get("multiple_shooting"),
                      {"segment_steps", "continuity_weight", "continuity_scale", "jumping_sensors",
                       "event_window", "hold_states_first"});
    if (s.Has("segment_steps")) c.options.segment_steps = segment_steps(s.Get("segment_steps"));
    if (s.Has("continuity_weight")) {
      c.options.continuity_weight = Positive(s.Get("continuity_weight"));
    }
    // continuity_scale: relative (the default: to the sensors) or absolute
    if (s.Has("continuity_scale")) {
      const Field f = s.Get("continuity_scale");
      const std::string v = f.node.IsScalar() ? f.node.Scalar() : "";
      if (v != "relative" && v != "absolute") {
        Fail(f.mark, f.path + ": expected 'relative' or 'absolute', got " + Quote(v),
             "multiple_shooting: {continuity_scale: relative|absolute}");
      }
      c.options.continuity_relative = v == "relative";
    }
    // jumping_sensors: omit (the default: left out under auto's contact segments) or fit
    if (s.Has("jumping_sensors")) {
      const Field f = s.Get("jumping_sensors");
      const std::string v = f.node.IsScalar() ? f.node.Scalar() : "";
      if (v != "omit" && v != "fit") {
        Fail(f.mark, f.path + ": expected 'omit' or 'fit', got " + Quote(v),
             "multiple_shooting: {jumping_sensors: omit|fit}");
      }
      c.options.fit_jumping_sensors = v == "fit";
    }
    // event_window: samples either side of a contact event left out (sysid/event_windows.h)
    if (s.Has("event_window")) {
      c.options.event_window = static_cast<int>(Integer(s.Get("event_window"), 0, 1000));
    }
    // hold_states_first: auto's contact segments start with their states held on the data
    if (s.Has("hold_states_first")) {
      const Field f = s.Get("hold_states_first");
      const std::string v = f.node.IsScalar() ? f.node.Scalar() : "";
      if (v != "true" && v != "false") {
        Fail(f.mark, f.path + ": expected true or false, got " + Quote(v),
             "multiple_shooting: {hold_states_first: true|false}");
      }
      c.options.hold_states_first = v == "true";
    }
  }
  if (r.Has("states")) ParseStates(r.Get("states"), &c);
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

void Parser::ParseSequences(const Field& f, ExperimentConfig* c,
                            std::vector<SequenceRef> ExperimentConfig::*into) const {
  std::vector<std::string> model_names;
  for (const ModelSpec& m : c->models) model_names.push_back(m.name);
  for (const Field& item : List(f)) {
    SequenceRef ref;
    // a name, or {name, start, end}: a window of the sequence (seconds)
    Field name_field = item;
    if (!item.node.IsScalar()) {
      const MapReader window(*this, item, {"name", "start", "end"});
      window.Require("name");
      name_field = window.Get("name");
      if (window.Has("start")) ref.start = Finite(window.Get("start"));
      if (window.Has("end")) ref.end = Finite(window.Get("end"));
      if (!(ref.start < ref.end)) {
        Fail(item.mark, item.path + ": the window's start must be before its end",
             "start and end are times in seconds on the log's clock");
      }
    }
    ref.name = Name(name_field);
    ref.mark = name_field.mark;
    const size_t slash = ref.name.find('/');
    if (c->models.size() > 1 && slash != std::string::npos) {
      ref.model = ref.name.substr(0, slash);
      ref.name = ref.name.substr(slash + 1);
      if (!c->FindModel(ref.model)) {
        Fail(item.mark,
             item.path + ": unknown model " + Quote(ref.model) + " in " +
                 Quote(name_field.node.Scalar()),
             NamesHint(ref.model, model_names, "models"));
      }
      if (ref.name.empty()) Fail(item.mark, item.path + ": the sequence name is empty");
    }
    for (const SequenceRef& seen : c->*into) {
      if (seen.model == ref.model && seen.name == ref.name) {
        Fail(item.mark, "duplicate sequence " + Quote(name_field.node.Scalar()),
             "first given at line " + std::to_string(seen.mark.line));
      }
    }
    (c->*into).push_back(std::move(ref));
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
    throw ParameterErrorAt(p, e);
  }

  // value, bounds, transform
  r.Require("initial", "the starting value of the fit, or auto");
  const Field fi = r.Get("initial");
  // `auto`: the equation-error start (sysid/equation_error.h), decided by the fit; NaN until then
  p.initial_auto = fi.node.IsScalar() && fi.node.Scalar() == "auto";
  p.initial = p.initial_auto ? std::numeric_limits<double>::quiet_NaN() : Finite(fi);
  if (r.Has("bounds")) {
    Bounds(r.Get("bounds"), &p.lower, &p.upper);
    if (!p.initial_auto && (p.initial < p.lower || p.initial > p.upper)) {
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
    if (!p.initial_auto && !(p.initial > 0)) {
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

// controls: {hold: zoh|linear | {<actuator>: zoh|linear}, delay: s | {initial, fit, bounds} |
// {<actuator>: s | {initial, fit, bounds}}}; a map with any of initial/fit/bounds is one delay
// for every actuator, any other map names actuators (checked against the model later)
void Parser::ParseControls(const Field& f, ExperimentConfig* c) const {
  const MapReader s(*this, f, {"hold", "delay"});
  // the entries of an actuator-keyed map, in file order, each name once
  auto by_actuator = [&](const Field& m, auto&& each) {
    std::vector<std::string> seen;
    for (auto it = m.node.begin(); it != m.node.end(); ++it) {
      const Mark key_mark = At(it->first, m.mark);
      const std::string name = it->first.IsScalar() ? it->first.Scalar() : "";
      if (name.empty()) Fail(key_mark, m.path + ": expected actuator names as keys");
      if (std::find(seen.begin(), seen.end(), name) != seen.end()) {
        Fail(key_mark, m.path + ": actuator " + Quote(name) + " given twice");
      }
      seen.push_back(name);
      each(name, key_mark, Field{it->second, At(it->second, key_mark), m.path + "." + name});
    }
  };
  if (s.Has("hold")) {
    const Field fh = s.Get("hold");
    if (fh.node.IsMap()) {
      by_actuator(fh, [&](const std::string& name, const Mark& key, const Field& value) {
        c->control_holds.emplace_back(name, static_cast<ControlHold>(Enum(value, kControlHolds)));
        c->control_hold_marks.push_back(key);
      });
    } else {
      c->control_hold = static_cast<ControlHold>(Enum(fh, kControlHolds));
    }
  }
  if (!s.Has("delay")) return;
  const Field fd = s.Get("delay");
  if (!fd.node.IsMap()) {
    c->control_delay = NonNegative(fd);
    return;
  }
  // one term: a number (given) or {initial, fit, bounds}
  auto term = [&](const Field& value, ExperimentConfig::ControlDelaySpec* spec) {
    if (value.node.IsMap()) {
      ParseTerm(value, true, &spec->term, &spec->marks);
    } else {
      spec->term.initial = NonNegative(value);
    }
  };
  const bool shared =
      fd.node["initial"].IsDefined() || fd.node["fit"].IsDefined() || fd.node["bounds"].IsDefined();
  if (shared) {
    ExperimentConfig::ControlDelaySpec spec;
    spec.mark = fd.mark;
    term(fd, &spec);
    if (!spec.term.fit) {
      c->control_delay = spec.term.initial;  // given: the plain shared delay
      return;
    }
    c->control_delays.push_back(std::move(spec));
    return;
  }
  by_actuator(fd, [&](const std::string& name, const Mark& key, const Field& value) {
    ExperimentConfig::ControlDelaySpec spec;
    spec.actuator = name;
    spec.mark = key;
    term(value, &spec);
    c->control_delays.push_back(std::move(spec));
  });
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

// states: {qpos: {sigma, joints}, qvel: {sigma, joints}, act: {sigma, actuators}}; sigma a
// positive number (shared) or a list with one per name (then the names must be given); marks
// under "<part>", "<part>.sigma" and "<part>.<joints|actuators>[i]"
void Parser::ParseStates(const Field& f, ExperimentConfig* c) const {
  const MapReader r(*this, f, {"qpos", "qvel", "act"});
  c->states_marks = r.marks();
  FitStates& st = c->options.states;
  FitStates::Part* parts[3] = {&st.qpos, &st.qvel, &st.act};
  const char* names[3] = {"qpos", "qvel", "act"};
  for (int i = 0; i < 3; ++i) {
    if (!r.Has(names[i])) continue;
    const std::string objects = i == 2 ? "actuators" : "joints";
    const MapReader pr(*this, r.Get(names[i]), {"sigma", objects});
    pr.Require("sigma", "the noise level of the logged " + std::string(names[i]) +
                            ": one positive number, or a list with one per name in '" + objects +
                            "'");
    FitStates::Part& part = *parts[i];
    part.fit = true;
    const std::string at = std::string(names[i]) + ".";
    c->states_marks.keys[at + "sigma"] = pr.Get("sigma").mark;
    if (pr.Has(objects)) {
      const std::vector<Field> items = List(pr.Get(objects));
      for (size_t k = 0; k < items.size(); ++k) {
        part.names.push_back(Name(items[k]));
        for (size_t j = 0; j < k; ++j) {
          if (part.names[j] == part.names[k]) {
            Fail(items[k].mark, items[k].path + ": " + Quote(part.names[k]) + " given twice");
          }
        }
        c->states_marks.keys[at + objects + "[" + std::to_string(k) + "]"] = items[k].mark;
      }
      if (items.empty()) {
        Fail(pr.Get(objects).mark, pr.Path(objects) + " is empty",
             "leave it out to fit every one of the model's " + objects);
      }
    }
    const Field sigma = pr.Get("sigma");
    if (sigma.node.IsSequence()) {
      for (const Field& item : List(sigma)) part.sigma.push_back(Positive(item));
      if (part.sigma.size() != part.names.size()) {
        Fail(sigma.mark,
             sigma.path + " has " + std::to_string(part.sigma.size()) + " values for " +
                 std::to_string(part.names.size()) + " " + objects,
             "give one sigma per entry of '" + objects + "', or one number for all");
      }
    } else {
      part.sigma.push_back(Positive(sigma));
    }
  }
}

void Parser::ParseSolver(const Field& f, ExperimentConfig* c) const {
  const MapReader r(*this, f,
                    {"max_iterations", "function_tolerance", "gradient_tolerance",
                     "parameter_tolerance", "jacobian", "differences", "relative_step", "threads",
                     "loss", "verbose", "starts", "seed", "reduce_model", "gauss_newton_stop"});
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
  // the reduced model (core/reduced_model.h)
  if (r.Has("reduce_model")) o->reduce_model = Bool(r.Get("reduce_model"));
  // the statistical stop (sysid/gn_convergence.h): a fraction of a standard error, 0 = off
  if (r.Has("gauss_newton_stop")) {
    o->gauss_newton_stop = NonNegative(r.Get("gauss_newton_stop"));
  }
  // multi-start (sysid/run/multi_start.h)
  if (r.Has("starts")) c->starts = static_cast<int>(Integer(r.Get("starts"), 1, 10000));
  if (r.Has("seed")) {
    c->start_seed = static_cast<std::uint64_t>(
        Integer(r.Get("seed"), 0, std::numeric_limits<long long>::max()));
  }
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
  const MapReader r(*this, f,
                    {"truth", "sequences", "steps", "seed", "excitation", "noise", "initial_state",
                     "sample_rate", "jitter", "drop"});
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

  // logged as a robot logs: sample rate (Hz), stamp jitter (s), fraction of rows dropped
  if (r.Has("sample_rate")) {
    const Field fr = r.Get("sample_rate");
    s->sample_rate = Finite(fr);
    if (s->sample_rate <= 0) {
      Fail(fr.mark, fr.path + ": a sample rate must be > 0 Hz, got " + FormatNumber(s->sample_rate),
           "leave it out for one sample per simulation step");
    }
  }
  if (r.Has("jitter")) {
    const Field fj = r.Get("jitter");
    s->jitter = Finite(fj);
    if (s->jitter < 0 || !r.Has("sample_rate") || s->jitter >= 0.5 / s->sample_rate) {
      Fail(fj.mark, fj.path + ": jitter must be >= 0 s and below half a sample period (it needs " +
                        r.Path("sample_rate") + "), got " + FormatNumber(s->jitter));
    }
  }
  if (r.Has("drop")) {
    const Field fd = r.Get("drop");
    s->drop = Finite(fd);
    if (s->drop < 0 || s->drop >= 0.5 || !r.Has("sample_rate")) {
      Fail(fd.mark, fd.path + ": drop is the fraction of rows dropped, 0 <= drop < 0.5 (it needs " +
                        r.Path("sample_rate") + "), got " + FormatNumber(s->drop));
    }
  }
}

}  // namespace

// core's ParameterError as a ConfigError at the parameter's key it is about, with core's message
// (followed by context) and hint
ConfigError ParameterErrorAt(const ParameterSpec& p, const ParameterError& e,
                             const std::string& context) {
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

// ---------------------------------------------------------------------------------------------
// public api

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

}  // namespace mjsysid::io
