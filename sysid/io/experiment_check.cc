#include <filesystem>
#include <string>
#include <vector>

#include "core/parameters.h"
#include "core/text.h"
#include "sysid/io/experiment.h"
#include "sysid/io/yaml_reader.h"

namespace mjsysid::io {
namespace {

namespace fs = std::filesystem;

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
    throw ParameterErrorAt(p, e, " in " + label);
  }
}

// A body kind on a body welded to the world that core accepted because a sensor can read it
// (SensorsReadingBody): with a `sensors:` list, one of the listed sensors must be such a sensor,
// or the parameter moves nothing that is fitted (its computed column is rounding noise)
void CheckWeldedBodyIsRead(const ExperimentConfig& config, const ParameterSpec& p, const mjModel& m,
                           const std::string& label) {
  const std::string& kind = p.target.kind;
  if (config.sensors.empty() || kind.rfind("body_", 0) != 0) return;
  const int b = mj_name2id(&m, mjOBJ_BODY, p.target.object.c_str());
  if (b <= 0 || !BodyWeldedToWorld(m, b)) return;
  std::vector<std::string> readers;
  for (int s : SensorsReadingBody(m, b)) {
    const char* name = mj_id2name(&m, mjOBJ_SENSOR, s);
    readers.emplace_back(name ? name : "sensor " + std::to_string(s));
    for (const SensorSpec& fitted : config.sensors) {
      if (fitted.name == readers.back()) return;
    }
  }
  throw ConfigError(
      p.marks.Of("object"),
      kind + ": body " + Quote(p.target.object) + " is welded to the world (no " +
          "joint between it and the world) in " + label +
          ": it moves no state, and none of the fitted sensors reads it",
      "fit a sensor that reads it (" + JoinNames(readers) + "), or remove the parameter");
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
    if (!p.AppliesTo(model_name)) continue;
    ValidateParameter(p, m, label);
    CheckWeldedBodyIsRead(config, p, m, label);
  }
  for (const MeasurementSpec& ms : config.measurement) {
    CheckSensor(m, ms.sensor, ms.marks.Of("sensor"), label);
  }

  // controls: the actuators given their own hold or delay
  auto require_actuator = [&](const std::string& key, const std::string& name, const Mark& mark) {
    if (mj_name2id(&m, mjOBJ_ACTUATOR, name.c_str()) >= 0) return;
    throw ConfigError(mark, key + ": no actuator named " + Quote(name) + " in " + label,
                      NamesHint(name, ObjectNames(m, mjOBJ_ACTUATOR, m.nu), "actuator names"));
  };
  for (size_t k = 0; k < config.control_holds.size(); ++k) {
    const std::string& name = config.control_holds[k].first;
    require_actuator("controls.hold." + name, name, config.control_hold_marks[k]);
  }
  for (const ExperimentConfig::ControlDelaySpec& cd : config.control_delays) {
    if (!cd.actuator.empty()) {
      require_actuator("controls.delay." + cd.actuator, cd.actuator, cd.mark);
    }
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

  // states: the joints and actuators named (sysid/solve/state_residuals.h)
  const FitStates& st = config.options.states;
  for (const auto& [part, joints] :
       {std::pair<const char*, const FitStates::Part*>{"qpos", &st.qpos}, {"qvel", &st.qvel}}) {
    for (size_t k = 0; k < joints->names.size(); ++k) {
      RequireObject(
          m, mjOBJ_JOINT, m.njnt, "joint", joints->names[k],
          config.states_marks.Of(std::string(part) + ".joints[" + std::to_string(k) + "]"), label);
    }
  }
  for (size_t k = 0; k < st.act.names.size(); ++k) {
    const Mark& mark = config.states_marks.Of("act.actuators[" + std::to_string(k) + "]");
    const int id = RequireObject(m, mjOBJ_ACTUATOR, m.nu, "actuator", st.act.names[k], mark, label);
    if (m.actuator_actadr[id] < 0) {
      throw ConfigError(mark, "actuator " + Quote(st.act.names[k]) + " of " + label +
                                  " has no activation (no dyntype): nothing to fit in states.act");
    }
  }
  if (st.act.fit && st.act.names.empty() && m.na == 0) {
    throw ConfigError(config.states_marks.Of("act"),
                      "states.act: " + label + " has no actuator with an activation (na = 0)");
  }
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
