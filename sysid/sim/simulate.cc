#include "sysid/sim/simulate.h"

#include <mujoco/mujoco.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <map>
#include <random>
#include <string>
#include <vector>

#include "core/mujoco_env.h"
#include "core/parameters.h"
#include "core/simulator.h"
#include "core/text.h"
#include "mjsysid/version.h"
#include "sysid/data/sample_grid.h"
#include "sysid/sim/excitation.h"
#include "sysid/solve/residual_model.h"

namespace mjsysid::sim {
namespace {

// a number as text that reads back to the same double
std::string JoinNumbers(const std::vector<double>& values) {
  std::string out;
  for (double v : values) out += (out.empty() ? "" : ",") + FormatG17(v);
  return out;
}

std::string Join(const std::vector<std::string>& names) {
  std::string out;
  for (const std::string& n : names) out += (out.empty() ? "" : ",") + n;
  return out;
}

// the mark of a model entry (its path)
const io::Mark& ModelMark(const io::ExperimentConfig& config, const io::ModelSpec& spec) {
  return config.model_list ? spec.marks.Of("path") : spec.marks.self;
}

// every truth entry names a parameter or a fitted control delay, with a finite value
void CheckTruth(const io::ExperimentConfig& config) {
  std::vector<std::string> names;
  for (const io::ParameterSpec& p : config.parameters) names.push_back(p.name);
  const size_t parameters = names.size();
  for (const io::ExperimentConfig::ControlDelaySpec& cd : config.control_delays) {
    if (cd.term.fit) names.push_back(FitControlDelay{cd.actuator}.Name());
  }
  const bool delays = names.size() > parameters;
  for (const io::NamedValue& t : config.simulate.truth) {
    if (!config.FindParameter(t.name) && !config.FindFittedControlDelay(t.name)) {
      // a delay's name (or an experiment with fitted delays) says that delays have truths too
      const bool say = delays || t.name.rfind("controls.delay", 0) == 0;
      throw io::ConfigError(t.mark,
                            "simulate.truth: '" + t.name + "' is not a parameter" +
                                (say ? " nor a fitted control delay" : ""),
                            names.empty() ? "the experiment has no parameters"
                            : delays      ? "parameters and fitted control delays: " + Join(names)
                                          : "parameters: " + Join(names));
    }
    if (!std::isfinite(t.value)) {
      throw io::ConfigError(t.mark, "simulate.truth." + t.name + ": the value must be finite");
    }
  }
}

// the initial state of every sequence: simulate.initial_state, else qpos0 and zero velocity
InitialState InitialStateOf(const io::ExperimentConfig& config, const Simulator& sim) {
  InitialState x0 = sim.ReferenceState();
  const io::SimulateInitialState& is = config.simulate.initial_state;
  if (!is.qpos.empty()) x0.qpos = Eigen::Map<const Eigen::VectorXd>(is.qpos.data(), is.qpos.size());
  if (!is.qvel.empty()) x0.qvel = Eigen::Map<const Eigen::VectorXd>(is.qvel.data(), is.qvel.size());
  x0.time = 0;
  return x0;
}

// sensor names and dimensions of a model, in model order; every sensor must be named
void SensorColumns(const io::ExperimentConfig& config, const io::ModelSpec& spec, const mjModel& m,
                   std::vector<std::string>* names, std::vector<int>* dims) {
  for (int i = 0; i < static_cast<int>(m.nsensor); ++i) {
    const char* name = mj_id2name(&m, mjOBJ_SENSOR, i);
    if (!name || !*name) {
      throw io::ConfigError(ModelMark(config, spec),
                            "model '" + spec.name + "': sensor " + std::to_string(i) +
                                " has no name; logs name every sensor column",
                            "add name=\"...\" to every sensor of " + spec.path);
    }
    names->push_back(name);
    dims->push_back(m.sensor_dim[i]);
  }
}

// the value each fitted control delay is simulated at: its truth (simulate.truth), else its
// initial value; by FitControlDelay::Name()
std::map<std::string, double> DelayTruths(const io::ExperimentConfig& config) {
  std::map<std::string, double> out;
  for (const io::ExperimentConfig::ControlDelaySpec& cd : config.control_delays) {
    if (cd.term.fit) out[FitControlDelay{cd.actuator}.Name()] = cd.term.initial;
  }
  for (const io::NamedValue& t : config.simulate.truth) {
    if (out.count(t.name)) out[t.name] = t.value;
  }
  return out;
}

// per-parameter true values of every model, for the attributes
struct TruthRecord {
  std::vector<std::pair<std::string, double>> by_model;  // (model, value)
  bool from_model = false;                               // no truth entry: the model's value
};

// The instants a robot logs at (simulate.sample_rate, jitter, drop): t_0 = 0, then k / rate moved
// by uniform(-jitter, jitter), up to the last simulation step's time; then round(drop T) rows other
// than the first and last dropped at random. Strictly increasing (jitter < half a period).
std::vector<double> RobotSampleTimes(const io::SimulateOptions& so, double duration,
                                     std::uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> jitter(-so.jitter, so.jitter);
  std::vector<double> times = {0.0};
  const double period = 1.0 / so.sample_rate;
  for (int k = 1; k * period + so.jitter <= duration; ++k) {
    times.push_back(k * period + (so.jitter > 0 ? jitter(rng) : 0.0));
  }
  const int drops = static_cast<int>(std::round(so.drop * static_cast<double>(times.size())));
  for (int d = 0; d < drops && times.size() > 2; ++d) {
    std::uniform_int_distribution<size_t> row(1, times.size() - 2);
    times.erase(times.begin() + static_cast<long>(row(rng)));
  }
  return times;
}

// rows of `steps` (N x n, one per simulation step) read at the samples' positions (in steps) by
// the fit's own interpolation (DelayedSample, delay 0): T x n
RowMatrix ReadAtPositions(const RowMatrix& steps, const std::vector<double>& position, double dt) {
  RowMatrix out(static_cast<Eigen::Index>(position.size()), steps.cols());
  for (size_t k = 0; k < position.size(); ++k) {
    const DelayedSample at(position[k], static_cast<int>(steps.rows()), 0.0, dt);
    for (Eigen::Index c = 0; c < steps.cols(); ++c) {
      out(static_cast<Eigen::Index>(k), c) = at.Value(Signal{steps.data() + c, steps.cols()});
    }
  }
  return out;
}

// interpolated qpos rows: the quaternions of ball and free joints normalised again
void NormalizeQuaternions(const mjModel& m, RowMatrix* qpos) {
  for (int j = 0; j < m.njnt; ++j) {
    const int type = m.jnt_type[j];
    if (type != mjJNT_BALL && type != mjJNT_FREE) continue;
    const int adr = m.jnt_qposadr[j] + (type == mjJNT_FREE ? 3 : 0);
    for (Eigen::Index k = 0; k < qpos->rows(); ++k) mju_normalize4(qpos->row(k).data() + adr);
  }
}

}  // namespace

std::string SimulatedSequenceName(const io::ExperimentConfig& config, const std::string& model,
                                  int s) {
  const std::string base = "seq" + std::to_string(s);
  return config.models.size() > 1 ? model + "_" + base : base;
}

io::Log SimulateExperiment(const io::ExperimentConfig& config, const SimulateSettings& settings) {
  InstallMujocoHandlers();
  const io::SimulateOptions& so = config.simulate;
  CheckTruth(config);
  if (config.models.empty()) {
    throw io::ConfigError(config.marks.self, "the experiment names no model");
  }
  if (so.sequences < 1 || so.steps < 1) {
    throw io::ConfigError(so.marks.self, "simulate: sequences and steps must be >= 1");
  }
  const bool several = config.models.size() > 1;

  io::Log log;
  log.sensor_time = "pre";
  std::map<std::string, std::string>& attr = log.attributes;
  std::map<std::string, TruthRecord> truth_records;
  const std::map<std::string, double> delay_truths = DelayTruths(config);

  for (size_t mi = 0; mi < config.models.size(); ++mi) {
    const io::ModelSpec& spec = config.models[mi];

    // the model, checked against the config
    ModelPtr model = LoadModel(spec.path);
    io::ValidateExperimentAgainstModel(config, *model, spec.name);
    const std::vector<const io::ParameterSpec*> used = config.ParametersOf(spec.name);
    std::vector<ParameterSpec> params;
    for (const io::ParameterSpec* p : used) params.push_back(p->target);
    std::vector<std::string> sensor_names;
    std::vector<int> sensor_dims;
    SensorColumns(config, spec, *model, &sensor_names, &sensor_dims);

    // the simulator at the true parameter values
    SimulatorOptions options;
    options.threads = settings.threads;
    options.sensors = true;
    Simulator sim(*model, params, options);
    Eigen::VectorXd values = sim.GetParameters();
    for (size_t i = 0; i < used.size(); ++i) {
      TruthRecord& rec = truth_records[used[i]->name];
      rec.from_model = true;
      for (const io::NamedValue& t : so.truth) {
        if (t.name == used[i]->name) {
          values[static_cast<Eigen::Index>(i)] = t.value;
          rec.from_model = false;
        }
      }
      rec.by_model.emplace_back(spec.name, values[static_cast<Eigen::Index>(i)]);
    }
    sim.SetParameters(values);

    // controls and initial states, then the rollouts (in parallel across sequences)
    const mjModel& m = sim.model();
    const StateDims& dims = sim.dims();
    const double dt = m.opt.timestep;
    std::vector<SequenceInput> inputs(so.sequences);
    // every actuator's hold rule and delay as the experiment states them (`controls:`; a fitted
    // delay at its truth), exactly as the fit holds them (ExperimentConfig::ActuatorControlsOf)
    const io::ExperimentConfig::ActuatorControls held = config.ActuatorControlsOf(m, delay_truths);
    // a robot's log (sample_rate): its sample instants, its controls logged at them, and where
    // each instant sits on the simulation grid; the rollout holds the logged controls exactly as
    // the fit does (BuildSampleGrid), so a noise-free log is reproduced by the true parameters.
    // One sample per step: the commands are logged, the rollout gets them held and delayed.
    std::vector<std::vector<double>> sample_times(so.sequences), positions(so.sequences);
    std::vector<RowMatrix> logged_ctrl(so.sequences);
    for (int s = 0; s < so.sequences; ++s) {
      inputs[s].x0 = InitialStateOf(config, sim);
      inputs[s].ctrl = GenerateControls(m, so.excitation, so.steps, so.seed + s);
      if (so.sample_rate <= 0) {
        logged_ctrl[s] = inputs[s].ctrl;
        Eigen::VectorXd t(so.steps);
        for (int k = 0; k < so.steps; ++k) t[k] = k * dt;
        inputs[s].ctrl =
            BuildSampleGrid(t, so.steps, 0.0, logged_ctrl[s], Eigen::VectorXd(), held.hold,
                            held.delay, dt, "simulate: sequence " + std::to_string(s),
                            config.control_before)
                .ctrl;
        continue;
      }
      const std::vector<double>& times = sample_times[s] =
          RobotSampleTimes(so, (so.steps - 1) * dt, SeedFor(so.seed + s, kSampleStream + mi));
      RowMatrix& uk = logged_ctrl[s];
      uk.resize(static_cast<Eigen::Index>(times.size()), dims.nu);
      for (size_t k = 0; k < times.size(); ++k) {
        const int n = std::min(so.steps - 1, static_cast<int>(std::floor(times[k] / dt + 1e-9)));
        uk.row(static_cast<Eigen::Index>(k)) = inputs[s].ctrl.row(n);
      }
      const Eigen::VectorXd t = Eigen::Map<const Eigen::VectorXd>(times.data(), times.size());
      const SampleGrid grid = BuildSampleGrid(
          t, static_cast<int>(times.size()), 0.0, uk, Eigen::VectorXd(), held.hold, held.delay, dt,
          "simulate: sequence " + std::to_string(s), config.control_before);
      inputs[s].ctrl = grid.ctrl;
      positions[s] = grid.position;
    }
    if (settings.progress) {
      settings.progress("model " + spec.name + ": " + std::to_string(so.sequences) + " sequence" +
                        (so.sequences > 1 ? "s" : "") + " x " + std::to_string(so.steps) +
                        " steps");
    }
    std::vector<Trajectory> traj;
    if (settings.rollout) {
      settings.rollout(sim, inputs, &traj);
    } else {
      sim.Rollout(inputs, &traj);
    }

    // one log sequence per rollout
    std::vector<std::string> actuator_names;
    for (int i = 0; i < dims.nu; ++i) {
      const char* name = mj_id2name(&m, mjOBJ_ACTUATOR, i);
      actuator_names.push_back(name ? name : "");
    }
    std::vector<std::string> names;
    for (int s = 0; s < so.sequences; ++s) {
      io::Sequence seq;
      seq.name = SimulatedSequenceName(config, spec.name, s);
      if (so.sample_rate <= 0) {
        // one sample per simulation step
        const int T = so.steps;
        seq.time.resize(T);
        for (int k = 0; k < T; ++k) seq.time[k] = k * dt;
        seq.ctrl = logged_ctrl[s];  // the commands, before any delay
        seq.sensordata = traj[s].sensors;
        seq.qpos = traj[s].states.block(0, 0, T, dims.nq);
        seq.qvel = traj[s].states.block(0, dims.nq, T, dims.nv);
        if (dims.na > 0) seq.act = traj[s].states.block(0, dims.nq + dims.nv, T, dims.na);
      } else {
        // at the robot's instants: sensors and states interpolated between the steps around each
        const std::vector<double>& times = sample_times[s];
        seq.time = Eigen::Map<const Eigen::VectorXd>(times.data(), times.size());
        seq.ctrl = logged_ctrl[s];
        seq.sensordata = ReadAtPositions(traj[s].sensors, positions[s], dt);
        const RowMatrix states = ReadAtPositions(traj[s].states, positions[s], dt);
        const Eigen::Index T = states.rows();
        seq.qpos = states.block(0, 0, T, dims.nq);
        NormalizeQuaternions(m, &seq.qpos);
        seq.qvel = states.block(0, dims.nq, T, dims.nv);
        if (dims.na > 0) seq.act = states.block(0, dims.nq + dims.nv, T, dims.na);
      }
      AddSensorNoise(m, so.noise, SeedFor(so.seed + s, kNoiseStream + mi), &seq.sensordata);
      seq.sensor_names = sensor_names;
      seq.sensor_dims = sensor_dims;
      seq.actuator_names = actuator_names;
      names.push_back(seq.name);
      log.sequences.push_back(std::move(seq));
    }

    // per-model attributes
    if (several) {
      attr["model." + spec.name] = spec.path;
      attr["timestep." + spec.name] = FormatG17(dt);
      attr["sequences." + spec.name] = Join(names);
    } else {
      attr["model"] = spec.path;
      attr["timestep"] = FormatG17(dt);
    }
  }

  // what was simulated, and how
  attr["generator"] = std::string("mjsysid ") + MJSYSID_VERSION + " simulate";
  attr["mujoco_version"] = MujocoVersion();
  attr["experiment"] = config.source_file;
  attr["name"] = config.name;
  attr["seed"] = std::to_string(so.seed);
  attr["sequences"] = std::to_string(so.sequences);
  attr["steps"] = std::to_string(so.steps);
  attr["excitation"] = DescribeExcitation(so.excitation);
  if (so.sample_rate > 0) {
    attr["sample_rate"] = FormatG17(so.sample_rate);
    attr["jitter"] = FormatG17(so.jitter);
    attr["drop"] = FormatG17(so.drop);
  }
  for (const io::NamedValue& n : so.noise) attr["noise." + n.name] = FormatG17(n.value);
  std::vector<std::string> from_model;
  for (const io::ParameterSpec& p : config.parameters) {
    auto it = truth_records.find(p.name);
    if (it == truth_records.end()) continue;
    const TruthRecord& rec = it->second;
    if (rec.from_model) from_model.push_back(p.name);
    bool same = true;
    for (const auto& entry : rec.by_model) same = same && entry.second == rec.by_model[0].second;
    if (same) {
      attr["truth." + p.name] = FormatG17(rec.by_model[0].second);
    } else {
      for (const auto& [model_name, value] : rec.by_model) {
        attr["truth." + model_name + "." + p.name] = FormatG17(value);
      }
    }
  }
  if (!from_model.empty()) attr["truth_from_model"] = Join(from_model);
  // the fitted control delays as simulated (their truth, else their initial value)
  for (const auto& [name, value] : delay_truths) attr["truth." + name] = FormatG17(value);
  if (!so.initial_state.qpos.empty()) {
    attr["initial_state.qpos"] = JoinNumbers(so.initial_state.qpos);
  }
  if (!so.initial_state.qvel.empty()) {
    attr["initial_state.qvel"] = JoinNumbers(so.initial_state.qvel);
  }
  return log;
}

}  // namespace mjsysid::sim
