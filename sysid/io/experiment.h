// YAML experiment files (schema version 1, docs/experiment-schema.md): parsing into a plain
// ExperimentConfig, and checks of a parsed config against a compiled model.
//
// Contract:
// - LoadExperiment/ParseExperiment either return a config that satisfies every rule of the schema
//   that can be checked without a model, or throw ConfigError pointing at the offending YAML
//   element (file:line:column, 1-based) with a hint (valid keys, allowed values, "did you mean").
// - Paths (models, data, output) are resolved against the YAML file's directory and stored
//   absolute and normalised. Nothing is read besides the YAML file itself.
// - Parameter kinds, their objects and index ranges are core's (core/parameters.h): a parameter's
//   error carries core's message and hint, at the YAML key it is about.
// - Every element keeps its source Mark, so that checks made later against a model
//   (ValidateExperimentAgainstModel, or a caller's own) report the YAML position.
#pragma once

#include <mujoco/mujoco.h>

#include <cstdint>
#include <limits>
#include <map>
#include <optional>
#include <stdexcept>
#include <string>
#include <vector>

#include "core/parameters.h"
#include "sysid/io/marks.h"
#include "sysid/types.h"

namespace mjsysid::io {

// the schema version this loader reads (the optional top-level key `version`)
inline constexpr int kExperimentSchemaVersion = 1;

// one model: `model: PATH` gives a single entry named after the file stem
struct ModelSpec {
  std::string name;
  std::string path;  // absolute
  Marks marks;
};

// one HDF5 log file
struct DataFile {
  std::string path;  // absolute
  Mark mark;
};

// one entry of `sequences`: "seq" or, with several models, "model/seq"
struct SequenceRef {
  std::string model;  // "" = the sequence of that name for every model
  std::string name;
  Mark mark;
  // the window fitted (`{name: ..., start: s, end: s}`): the samples with start <= time <= end
  // (seconds, the log's clock); the whole sequence by default
  double start = -std::numeric_limits<double>::infinity();
  double end = std::numeric_limits<double>::infinity();
};

// whether a log's sensor row at step k is read before (pre) or after (post) step k
enum class SensorTime { kPre, kPost };

// one residual channel group: a sensor and its weight (1/sigma when sigma is given)
struct SensorSpec {
  std::string name;
  std::optional<double> sigma;  // noise standard deviation, > 0
  // sigma: auto: the noise level estimated from the log (FitOptions::sensors_sigma_from_log)
  bool sigma_from_log = false;
  double weight = 1.0;  // > 0; unused when sigma is given or estimated
  Marks marks;

  // the factor applied to this sensor's residuals
  double ResidualWeight() const { return sigma ? 1.0 / *sigma : weight; }
};

// one physical parameter to identify (sysid/types.h: name, target = core's ParameterSpec with
// label = name, initial, bounds, transform, scale, prior, models), with the YAML marks of the
// entry and of its prior's map
struct ParameterSpec : FitParameter {
  Marks marks;
  Marks prior_marks;
};

// measured = gain * simulated(t - delay) + bias, per sensor (sysid/types.h), with the YAML marks
// of the entry and of each term's map
struct MeasurementSpec : FitMeasurement {
  Marks marks;
  Marks delay_marks, gain_marks, bias_marks;
};

enum class ExcitationType { kSines, kChirp, kPrbs, kZero, kFile };

// the control signal of one actuator (or of all, actuator == "") in `sysid simulate`
struct Excitation {
  std::string actuator;  // "" = every actuator
  ExcitationType type = ExcitationType::kSines;
  double amplitude = 1.0;                          // >= 0
  std::vector<double> frequencies{0.5, 1.3, 2.9};  // Hz, sines
  double f0 = 0.1;                                 // Hz, chirp start
  double f1 = 5.0;                                 // Hz, chirp end
  double switch_period = 0.1;                      // s, prbs
  std::string path;  // file: a CSV of controls (time, one column per actuator), absolute
  Marks marks;
};

// a name -> number entry (simulate.truth, simulate.noise), in file order
struct NamedValue {
  std::string name;
  double value = 0.0;
  Mark mark;  // of the key
};

// the initial state of simulated sequences; an empty vector = the model's default
struct SimulateInitialState {
  std::vector<double> qpos;
  std::vector<double> qvel;
  Marks marks;
};

// options of `sysid simulate`; marks.self.line == 0 when the block was not given
struct SimulateOptions {
  std::vector<NamedValue> truth;  // parameter name -> true value
  int sequences = 2;              // > 0
  int steps = 2000;               // > 0
  std::uint64_t seed = 42;
  std::vector<Excitation> excitation{Excitation{}};  // one for all, or one per actuator
  std::vector<NamedValue> noise;                     // sensor name -> sigma (>= 0)
  SimulateInitialState initial_state;
  Marks marks;
  // logged as a robot logs (sysid/sim/simulate.h): samples at sample_rate (Hz, > 0; 0: one per
  // simulation step), each instant but the first moved by uniform(-jitter, jitter) (s, >= 0,
  // below half a sample period), and a fraction `drop` (0 <= drop < 0.5) of the rows dropped
  double sample_rate = 0;
  double jitter = 0;
  double drop = 0;
};

// a whole experiment file
struct ExperimentConfig {
  int version = kExperimentSchemaVersion;
  std::string name;         // default: the YAML file's stem
  std::string source_file;  // the YAML file, absolute
  std::string base_dir;     // its directory, against which relative paths were resolved
  std::vector<ModelSpec> models;
  bool model_list = false;  // true when given as `models` (a list), false for `model`
  std::vector<DataFile> data;
  std::vector<SequenceRef> sequences;  // empty = every sequence in the data
  // held-out sequences (same spelling as `sequences`): simulated at the start and the estimate,
  // never fitted; never also in `sequences` (with `sequences` empty: every other sequence is
  // fitted)
  std::vector<SequenceRef> validation;
  SensorTime sensor_time = SensorTime::kPre;
  std::vector<SensorSpec> sensors;  // empty = every sensor, weight 1
  std::vector<ParameterSpec> parameters;
  std::vector<MeasurementSpec> measurement;
  // the fit's options from the blocks `solver` (iterations, tolerances, jacobian, differences,
  // relative_step, threads, loss, verbose), `initial_state` (estimate_initial_state) and
  // `multiple_shooting` (segment_steps, continuity_weight); sensor weights are in `sensors`
  FitOptions options;
  Marks solver_marks;  // of the keys of the `solver` block
  // solver.starts (1..10000): fits from that many starts spread in the bounds, the best kept;
  // solver.seed: the spread's seed (sysid/run/multi_start.h)
  int starts = 1;
  std::uint64_t start_seed = 0;
  // solver.memory_limit_gb (> 0): the fit is refused when its memory estimate exceeds it
  // (sysid/fit/memory_estimate.h); 0: absent, the default limit (a share of the machine's
  // available memory)
  double memory_limit_gb = 0;
  SimulateOptions simulate;
  std::string output;  // absolute; default <base_dir>/results/<name>
  Marks marks;
  // `controls`: how the logged commands reach the simulation steps (every actuator, every
  // sequence; docs/real-logs.md): the hold rule and a known transport delay (s, >= 0)
  ControlHold control_hold = ControlHold::kZeroOrder;
  double control_delay = 0;
  // the `states` block (logged states fitted as data, in options.states): keys "qpos", "qvel",
  // "act", "<part>.sigma" and "<part>.joints[i]" / "act.actuators[i]"
  Marks states_marks;
  // `controls` per actuator (docs/experiment-schema.md): `hold: {<actuator>: zoh|linear}` (the
  // actuators not named keep control_hold) and the delays given or fitted: `delay: {initial,
  // fit, bounds}` (actuator "" = every actuator) or `delay: {<actuator>: s | {initial, fit,
  // bounds}}` (the actuators not named: no delay). A given shared delay is control_delay alone.
  struct ControlDelaySpec {
    std::string actuator;  // "" = every actuator
    FitMeasurement::Term term{0.0, false, 0.0, std::numeric_limits<double>::infinity()};  // s
    Mark mark;    // the actuator's key (or the delay's value when shared)
    Marks marks;  // of its initial, fit, bounds keys
  };
  std::vector<std::pair<std::string, ControlHold>> control_holds;
  std::vector<Mark> control_hold_marks;  // the actuator keys of control_holds
  std::vector<ControlDelaySpec> control_delays;

  // `controls.before` (every actuator, every sequence): what an actuator gets before its first
  // logged command
  ControlBefore control_before = ControlBefore::kHold;

  // The hold rule and transport delay (s) of every actuator of model m (nu entries each), the one
  // rule of "which hold and delay does actuator i get": control_hold and control_delay, an
  // actuator's own entry over them; a fitted delay (FitControlDelay::Name(): "controls.delay" or
  // "controls.delay.<actuator>") at fitted[name] when given (an estimate, a simulation's truth),
  // else at its initial value.
  struct ActuatorControls {
    std::vector<ControlHold> hold;
    std::vector<double> delay;
  };
  ActuatorControls ActuatorControlsOf(const mjModel& m,
                                      const std::map<std::string, double>& fitted = {}) const;
  // the fitted control delay (`controls.delay` with fit: true) of that name, nullptr when none
  const ControlDelaySpec* FindFittedControlDelay(const std::string& name) const;

  // nullptr when absent
  const ParameterSpec* FindParameter(const std::string& name) const;
  const ModelSpec* FindModel(const std::string& name) const;
  // the parameters that apply to the named model ("" = every parameter), in file order
  std::vector<const ParameterSpec*> ParametersOf(const std::string& model_name) const;
};

// Reads and parses an experiment file. Throws ConfigError (naming the file when it cannot be
// read; at the offending element otherwise).
ExperimentConfig LoadExperiment(const std::string& path);

// Parses experiment text as if read from path_for_messages (used in marks, for the default name
// and to resolve relative paths). Throws ConfigError.
ExperimentConfig ParseExperiment(const std::string& yaml_text,
                                 const std::string& path_for_messages);

// Checks the names and sizes in config against model m, known in the config as model_name (its
// ModelSpec::name; "" = apply every parameter): sensors, parameters (each resolved by core's
// Parameter::Resolve: its ParameterError becomes a ConfigError at the offending key with core's
// message followed by " in <model>", and core's hint), measurement and noise sensors, excitation
// actuators, simulate.initial_state sizes (nq, nv), the joints and actuators of `states` (an
// actuator there must have an activation). Throws ConfigError at the first offending
// element, with a hint listing up to 20 valid names.
void ValidateExperimentAgainstModel(const ExperimentConfig& config, const mjModel& m,
                                    const std::string& model_name);

// core's ParameterError about parameter p as a ConfigError at the YAML key it is about (target,
// object, field or index), with core's message followed by context, and core's hint
ConfigError ParameterErrorAt(const ParameterSpec& p, const ParameterError& e,
                             const std::string& context = {});

// Throws ConfigError at the model entry whose file does not exist or is not a regular file.
void CheckModelFilesExist(const ExperimentConfig& config);

}  // namespace mjsysid::io
