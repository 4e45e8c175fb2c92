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
#include "sysid/io/experiment_internal.h"
#include "sysid/io/plain_name.h"
#include "sysid/io/yaml_reader.h"

namespace mjsysid::io {
namespace experiment_internal {
namespace {

const std::vector<std::string> kRootKeys = {
    "version",     "name",     "model",      "models",      "data",          "sequences",
    "sensor_time", "sensors",  "parameters", "measurement", "initial_state", "multiple_shooting",
    "solver",      "simulate", "output",     "validation",  "controls",      "states"};
const std::vector<std::string> kSensorTimes = {"pre", "post"};

}  // namespace

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
  if (const std::string why = PlainNameProblem(c.name); !why.empty()) {
    // the name becomes a folder name (results/NAME): one rule for such names (plain_name.h)
    Fail(
        r.Has("name") ? r.KeyMark("name") : c.marks.self,
        (r.Has("name") ? std::string("name: ")
                       : std::string("the experiment's name (its file name, no `name:` given): ")) +
            Quote(c.name) + " is not a plain name: " + why,
        std::string("the name is the experiment's default output folder results/NAME; give ") +
            kPlainNameRule);
  }

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
  if (r.Has("multiple_shooting")) ParseMultipleShooting(r.Get("multiple_shooting"), &c);
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

}  // namespace experiment_internal

namespace {

namespace fs = std::filesystem;
using experiment_internal::Parser;

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

ExperimentConfig::ActuatorControls ExperimentConfig::ActuatorControlsOf(
    const mjModel& m, const std::map<std::string, double>& fitted) const {
  ActuatorControls out;
  out.hold.assign(m.nu, control_hold);
  out.delay.assign(m.nu, control_delay);
  for (const auto& [actuator, hold] : control_holds) {
    const int id = mj_name2id(&m, mjOBJ_ACTUATOR, actuator.c_str());
    if (id >= 0) out.hold[id] = hold;
  }
  // the shared delay first (every actuator), then an actuator's own over it
  for (const bool own : {false, true}) {
    for (const ControlDelaySpec& cd : control_delays) {
      if (cd.actuator.empty() == own) continue;
      double value = cd.term.initial;
      if (cd.term.fit) {
        const auto it = fitted.find(FitControlDelay{cd.actuator}.Name());
        if (it != fitted.end()) value = it->second;
      }
      const int id = own ? mj_name2id(&m, mjOBJ_ACTUATOR, cd.actuator.c_str()) : -1;
      if (own && id < 0) continue;  // an actuator of another model
      for (int i = 0; i < m.nu; ++i) {
        if (!own || i == id) out.delay[i] = value;
      }
    }
  }
  return out;
}

const ExperimentConfig::ControlDelaySpec* ExperimentConfig::FindFittedControlDelay(
    const std::string& delay_name) const {
  for (const ControlDelaySpec& cd : control_delays) {
    if (cd.term.fit && FitControlDelay{cd.actuator}.Name() == delay_name) return &cd;
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