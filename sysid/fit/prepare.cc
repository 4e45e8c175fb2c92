// PrepareFit (sysid/fit/prepare.h): validates the inputs (names, shapes, bounds, the data that
// every parameter must move) and builds what a fit runs on, in seven stages: the parameters
// checked, the simulators with their parameters, the measurement-term and control-delay variables,
// the sequences (channels, controls, sample grids with the fitted control delays applied, initial
// states), the initial rollouts and Jacobians, the segments of single or multiple shooting (the
// auto horizon, sysid/solve/multiple_shooting.h) and the evaluation cache. The fit (sysid/fit/) and
// CheckJacobians run on the result.
#include "sysid/fit/prepare.h"

#include <ceres/ceres.h>
#include <ceres/gradient_checker.h>

#include <Eigen/SparseCore>
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <limits>
#include <map>
#include <memory>
#include <stdexcept>
#include <string>
#include <tuple>
#include <utility>
#include <vector>

#include "core/invariant.h"
#include "core/text.h"
#include "sysid/assess/derived_inertials.h"
#include "sysid/assess/fit_status.h"
#include "sysid/assess/interval_check.h"
#include "sysid/data/contact_channels.h"
#include "sysid/data/equation_error.h"
#include "sysid/data/event_windows.h"
#include "sysid/fit_observer.h"
#include "sysid/solve/cost_functions.h"
#include "sysid/solve/evaluation_cache.h"
#include "sysid/solve/multiple_shooting.h"
#include "sysid/solve/progress.h"
#include "sysid/solve/residual_model.h"
#include "sysid/solve/state_manifold.h"
#include "sysid/solve/state_residuals.h"
#include "sysid/solve/variable_manifold.h"

namespace mjsysid {

// -----------------------------------------------------------------------------------------------
// fitted control delays

std::vector<double> PreparedFit::ControlDelays(int q, const double* mv, int shifted,
                                               double shift) const {
  const FitSequence& sq = sequences[q];
  const std::vector<int>& var = ctrl_delay_var[q];
  std::vector<double> delay = sq.ctrl_delay;
  delay.resize(var.size(), 0.0);
  for (size_t i = 0; i < var.size(); ++i) {
    if (var[i] >= 0) delay[i] = mv[var[i]] + (var[i] == shifted ? shift : 0.0);
  }
  return delay;
}

bool PreparedFit::HoldControlsAt(int q, const double* mv) {
  if (mv == nullptr || !HasControlDelay(q)) return false;
  SampleGrid& grid = grids[q];
  const std::vector<double> delay = ControlDelays(q, mv);
  if (delay == grid.delay) return false;
  const FitSequence& sq = sequences[q];
  const double dt = models[ModelIndex(sq.model)].sim->model().opt.timestep;
  HoldControls(grid, sq.ctrl, sq.ctrl_hold, delay, dt, &grid.ctrl);
  grid.delay = delay;
  return true;
}

// -----------------------------------------------------------------------------------------------
// building

void CheckParametersMove(const PreparedFit& fit, const std::vector<bool>& moves) {
  for (size_t g = 0; g < fit.params.size(); ++g) {
    if (g >= moves.size() || !moves[g]) {
      throw ParameterError("parameter '" + fit.params[g].name +
                           "' has no effect on the simulated states or sensors of any sequence "
                           "(its Jacobian column is exactly zero): remove it or add data that "
                           "excites it");
    }
  }
}

// A sharded start (ShardStart) simulated only the owned sequences at the initial values:
// the others' rollouts there (no Jacobians), for the result's initial signals. Leaves the
// simulators at the initial parameters.
void RolloutUnowned(PreparedFit* fit_ptr, std::vector<Trajectory>* initial) {
  PreparedFit& fit = *fit_ptr;
  std::vector<double> z0(fit.params.size());
  for (size_t g = 0; g < z0.size(); ++g)
    z0[g] = fit.ToZ(static_cast<int>(g), fit.params[g].initial);
  for (auto& mo : fit.models) {
    std::vector<SequenceInput> ins;
    std::vector<int> which;
    for (size_t q = 0; q < fit.sequences.size(); ++q) {
      if (fit.sequences[q].model != mo.name || (*initial)[q].states.rows() > 0) continue;
      ins.push_back({fit.sequences[q].x0, fit.grids[q].ctrl});
      which.push_back(static_cast<int>(q));
    }
    if (ins.empty()) continue;
    ApplyVariables(fit.params, mo.global, z0.data(), mo.sim.get());
    std::vector<Trajectory> trs;
    mo.sim->Rollout(ins, &trs);
    for (size_t i = 0; i < which.size(); ++i) (*initial)[which[i]] = std::move(trs[i]);
  }
}

// -----------------------------------------------------------------------------------------------
// the stages of PrepareFit, in order

namespace {

// 1. parameters: bounds, transforms and initial values consistent, models named
void CheckParameters(const PreparedFit& fit) {
  for (const FitParameter& p : fit.params) {
    const std::string where = "parameter '" + p.name + "': ";
    if (!std::isfinite(p.initial)) throw std::invalid_argument(where + "initial value not finite");
    if (!(p.lower < p.upper)) throw std::invalid_argument(where + "lower bound >= upper bound");
    if (p.initial < p.lower || p.initial > p.upper) {
      throw std::invalid_argument(where + "initial value " + std::to_string(p.initial) +
                                  " outside its bounds");
    }
    if (p.transform == Transform::kLog && !(p.initial > 0)) {
      throw std::invalid_argument(where + "log transform needs a positive initial value");
    }
    if (p.transform == Transform::kLog && p.lower < 0) {
      throw std::invalid_argument(where + "log transform needs a lower bound >= 0");
    }
    if (p.transform == Transform::kScale && !(p.scale > 0)) {
      throw std::invalid_argument(where + "scale must be positive");
    }
    if (p.has_prior && !(p.prior_sigma > 0)) {
      throw std::invalid_argument(where + "prior sigma must be positive");
    }
    for (const std::string& mname : p.models) fit.ModelIndex(mname);
  }
}

// 2. simulators: each model with the parameters that apply to it; z at the initial values
void BuildSimulators(PreparedFit& fit, FitVariables& vars, SolveContext& solve,
                     const FitOptions& options) {
  const int np = static_cast<int>(fit.params.size());
  SimulatorOptions so;
  so.threads = options.threads;
  for (auto& mo : fit.models) {
    std::vector<ParameterSpec> specs;
    mo.global.clear();
    for (int g = 0; g < np; ++g) {
      const FitParameter& p = fit.params[g];
      if (!p.models.empty() &&
          std::find(p.models.begin(), p.models.end(), mo.name) == p.models.end()) {
        continue;
      }
      ParameterSpec spec = p.target;
      spec.label = p.name;
      specs.push_back(spec);
      mo.global.push_back(g);
    }
    if (mo.sim) {
      mo.retired_steps = mo.Steps();
      mo.retired_critical = mo.CriticalSteps();
      mo.retired_time = mo.Time();
    }
    try {
      mo.sim = std::make_unique<Simulator>(*mo.model, specs, so);
    } catch (const ParameterError& e) {
      throw ParameterError("model '" + mo.name + "': " + e.what());
    }
    mo.manifold = std::make_unique<StateManifold>(&mo.sim->model());
    mo.sim->SetStepProgress(options.observer ? solve.step_progress.get() : nullptr);
  }
  vars.z.resize(np);
  for (int g = 0; g < np; ++g) vars.z[g] = fit.ToZ(g, fit.params[g].initial);
}

// 3. the m block: the fitted measurement terms, then the fitted control delays (seconds, >= 0);
// the names of every variable, the m block's bounds and starts
void BuildTermVariables(PreparedFit& fit, FitVariables& vars, FitPlan* out) {
  vars.m.clear();
  fit.term_index.assign(fit.measurements.size(), TermIndex());
  out->names.clear();
  for (const FitParameter& p : fit.params) out->names.push_back(p.name);
  out->mbounds.clear();
  out->minitial.clear();
  auto push = [&](double initial, double lower, double upper, std::string name) {
    vars.m.push_back(initial);
    out->mbounds.emplace_back(lower, upper);
    out->minitial.push_back(initial);
    out->names.push_back(std::move(name));
  };
  for (size_t i = 0; i < fit.measurements.size(); ++i) {
    const FitMeasurement& me = fit.measurements[i];
    auto add = [&](const FitMeasurement::Term& t, int* index, const char* what) {
      if (!t.fit) return;
      if (t.initial < t.lower || t.initial > t.upper) {
        throw std::invalid_argument("measurement " + std::string(what) + " of sensor '" +
                                    me.sensor + "': initial value outside its bounds");
      }
      *index = static_cast<int>(vars.m.size());
      push(t.initial, t.lower, t.upper, me.sensor + "." + what);
    };
    add(me.delay, &fit.term_index[i].delay, "delay");
    add(me.gain, &fit.term_index[i].gain, "gain");
    add(me.bias, &fit.term_index[i].bias, "bias");
  }
  fit.control_delay_index.clear();
  for (const FitControlDelay& cd : fit.control_delays) {
    const std::string where = "control delay '" + cd.Name() + "': ";
    if (!std::isfinite(cd.initial)) throw std::invalid_argument(where + "initial value not finite");
    if (!(cd.lower >= 0)) throw std::invalid_argument(where + "lower bound must be >= 0 (seconds)");
    if (!(cd.lower < cd.upper)) throw std::invalid_argument(where + "lower bound >= upper bound");
    if (cd.initial < cd.lower || cd.initial > cd.upper) {
      throw std::invalid_argument(where + "initial value " + FormatDigits(cd.initial, 6) +
                                  " outside its bounds");
    }
    fit.control_delay_index.push_back(static_cast<int>(vars.m.size()));
    push(cd.initial, cd.lower, cd.upper, cd.Name());
  }
}

// "R x C"
std::string Shape(Eigen::Index rows, Eigen::Index cols) {
  return std::to_string(rows) + " x " + std::to_string(cols);
}

// 4a. a sequence's matrices against its model: measured T x ns, ctrl Tc x nu, times, holds,
// delays, the initial state and the logged states. Each message names the member and the sizes
// expected and found (a Python caller's keys have the same names, python/src/fit_api.cc).
void CheckSequenceShapes(const FitSequence& sq, const StateDims& d, const std::string& where) {
  const Eigen::Index T = sq.measured.rows();
  const Eigen::Index Tc = sq.ctrl_time.size() ? sq.ctrl_time.size() : T;
  if (T < 1 || sq.measured.cols() != d.ns) {
    throw std::invalid_argument(where + "measured must be T x nsensordata = T x " +
                                std::to_string(d.ns) + " with T >= 1 (one row per sample, the " +
                                "model's sensor columns in model order), got " +
                                Shape(sq.measured.rows(), sq.measured.cols()));
  }
  if (sq.ctrl.rows() != Tc || sq.ctrl.cols() != d.nu) {
    throw std::invalid_argument(
        where + "ctrl must be " + Shape(Tc, d.nu) + " (" +
        (sq.ctrl_time.size() ? "one row per ctrl_time entry" : "one row per row of measured") +
        ", one column per actuator: nu = " + std::to_string(d.nu) + "), got " +
        Shape(sq.ctrl.rows(), sq.ctrl.cols()));
  }
  if (sq.time.size() != 0 && sq.time.size() != T) {
    throw std::invalid_argument(where + "time must be empty or have " + std::to_string(T) +
                                " entries (one per row of measured), got " +
                                std::to_string(sq.time.size()));
  }
  const std::pair<const char*, size_t> per_actuator[] = {{"ctrl_hold", sq.ctrl_hold.size()},
                                                         {"ctrl_delay", sq.ctrl_delay.size()}};
  for (const auto& [name, size] : per_actuator) {
    if (size != 0 && static_cast<int>(size) != d.nu) {
      throw std::invalid_argument(where + name + " must be empty or have one entry per actuator (" +
                                  std::to_string(d.nu) + "), got " + std::to_string(size));
    }
  }
  for (double delay : sq.ctrl_delay) {
    if (!(delay >= 0) || !std::isfinite(delay)) {
      throw std::invalid_argument(where + "a control delay must be finite and >= 0");
    }
  }
  // the logged states, when given: one row per sample (checked first: a caller may have taken
  // the initial state from their first row)
  const std::tuple<const char*, const RowMatrix*, int, const char*> logged[] = {
      {"qpos", &sq.qpos, d.nq, "nq"}, {"qvel", &sq.qvel, d.nv, "nv"}, {"act", &sq.act, d.na, "na"}};
  for (const auto& [name, x, n, dim] : logged) {
    if (x->rows() != 0 && (x->rows() != T || x->cols() != n)) {
      throw std::invalid_argument(where + "logged " + name + " must be T x " + dim + " = " +
                                  Shape(T, n) + " (one row per row of measured), got " +
                                  Shape(x->rows(), x->cols()));
    }
  }
  // the given initial state (empty parts: the model's qpos0, zeros)
  const std::tuple<const char*, const Eigen::VectorXd*, int, const char*> initial[] = {
      {"qpos", &sq.x0.qpos, d.nq, "nq"},
      {"qvel", &sq.x0.qvel, d.nv, "nv"},
      {"act", &sq.x0.act, d.na, "na"}};
  for (const auto& [name, x, n, dim] : initial) {
    if (x->size() != 0 && x->size() != n) {
      throw std::invalid_argument(where + "the initial " + name + " has " +
                                  std::to_string(x->size()) + " entries, expected " + dim + " = " +
                                  std::to_string(n) + " (the initial state is one row; logged " +
                                  "states are T x " + dim + ")");
    }
    for (Eigen::Index i = 0; i < x->size(); ++i) {
      if (!std::isfinite((*x)[i])) {
        throw std::invalid_argument(where + "the initial " + name + " is not finite at entry " +
                                    std::to_string(i) + " (" + FormatDigits((*x)[i], 6) +
                                    "; the simulation starts there: with logged states, their " +
                                    "first row unless given apart)");
      }
    }
  }
}

// 4b. sequence q's fitted sensor columns (channels, weights, measurement terms) and their
// unmeasured samples: NaN is not measured (masked, counted), Inf an error, a column with nothing
// left an error
void BuildChannels(PreparedFit& fit, const FitOptions& options, int q, const std::string& where) {
  const FitSequence& sq = fit.sequences[q];
  const FitModel& mo = fit.models[fit.ModelIndex(sq.model)];
  const mjModel& m = mo.sim->model();
  const int T = static_cast<int>(sq.measured.rows());
  std::vector<std::string> used = sq.sensors;
  if (sq.no_sensors && !used.empty()) {
    throw std::invalid_argument(where + "no_sensors is set and sensors are named");
  }
  if (used.empty() && !sq.no_sensors) {
    for (int i = 0; i < m.nsensor; ++i) {
      const char* nm = mj_id2name(&m, mjOBJ_SENSOR, i);
      used.push_back(nm ? nm : "");
    }
  }
  for (const std::string& sname : used) {
    const int id = mj_name2id(&m, mjOBJ_SENSOR, sname.c_str());
    if (id < 0) {
      throw std::invalid_argument(where + "no sensor named '" + sname + "' in model '" + mo.name +
                                  "'");
    }
    double weight = 1.0;
    const auto it = options.sensor_weights.find(sname);
    if (it != options.sensor_weights.end()) weight = it->second;
    if (!(weight > 0) || !std::isfinite(weight)) {
      throw std::invalid_argument("sensor '" + sname + "': weight must be positive");
    }
    int meas = -1;
    for (size_t i = 0; i < fit.measurements.size(); ++i) {
      if (fit.measurements[i].sensor == sname) meas = static_cast<int>(i);
    }
    for (int c = 0; c < m.sensor_dim[id]; ++c) {
      const int col = m.sensor_adr[id] + c;
      int missing = 0;
      for (int k = 0; k < T; ++k) {
        const double y = sq.measured(k, col);
        if (std::isnan(y)) {
          ++missing;
        } else if (!std::isfinite(y)) {
          throw std::invalid_argument(where + "measured sensor '" + sname +
                                      "' is not finite at row " + std::to_string(k));
        }
      }
      if (missing == T) {
        throw std::invalid_argument(where + "measured sensor '" + sname + "'" +
                                    (m.sensor_dim[id] > 1 ? " column " + std::to_string(c) : "") +
                                    " has no measured sample (all " + std::to_string(T) +
                                    " are NaN): nothing to fit");
      }
      fit.channels[q].push_back({col, weight, meas});
      fit.missing[q].push_back(missing);
    }
    if (std::find(fit.fitted[q].begin(), fit.fitted[q].end(), sname) == fit.fitted[q].end()) {
      fit.fitted[q].push_back(sname);
    }
  }
}

// 4c. controls: Inf is an error; NaN is held from the last valid value (warned), an error before
// the first one
void CheckControls(const FitSequence& sq, int nu, const std::string& where,
                   std::vector<std::string>* warnings) {
  const int Tc = static_cast<int>(sq.ctrl.rows());
  std::string held;
  int held_rows = 0;
  for (int i = 0; i < nu; ++i) {
    int first_valid = 0;
    while (first_valid < Tc && std::isnan(sq.ctrl(first_valid, i))) ++first_valid;
    if (first_valid > 0) {
      throw std::invalid_argument(
          where + "ctrl of actuator " + std::to_string(i) + " is NaN from row 0 to " +
          (first_valid < Tc ? "row " + std::to_string(first_valid - 1) : "the end") +
          ": a NaN control is held from the last valid value, and there is none before it");
    }
    for (int k = 0; k < Tc; ++k) {
      const double u = sq.ctrl(k, i);
      if (std::isinf(u)) {
        throw std::invalid_argument(where + "ctrl of actuator " + std::to_string(i) +
                                    " is infinite at row " + std::to_string(k));
      }
      if (std::isnan(u) && held_rows++ < 5) {
        held += (held.empty() ? "" : ", ") + std::to_string(k);
      }
    }
  }
  if (held_rows > 0) {
    warnings->push_back(where + std::to_string(held_rows) +
                        " NaN control value(s) held from the last valid " + "one (rows " + held +
                        (held_rows > 5 ? ", ..." : "") + ")");
  }
}

// 4d. the fitted control delay each actuator of sequence q follows (its own, else the shared
// one), if any; marks the delays used
void AssignControlDelays(PreparedFit& fit, int q, const mjModel& m, std::vector<bool>* used) {
  const std::vector<int> follows = ControlDelayOfActuators(fit.control_delays, m);
  fit.ctrl_delay_var[q].assign(m.nu, -1);
  for (int i = 0; i < m.nu; ++i) {
    const int c = follows[static_cast<size_t>(i)];
    if (c < 0) continue;
    fit.ctrl_delay_var[q][i] = fit.control_delay_index[c];
    (*used)[c] = true;
  }
}

// 4d, after the grid: a warning when the controls of sequence q's first steps read before an
// actuator's first logged command: its delay (given, or fitted: up to its upper bound, else from
// its initial value) reaches before it, or the commands start after the first sample. The steps of
// the rollout from the first sample (and so of the segment that starts there under multiple
// shooting) then use commands nobody logged: FitSequence::ctrl_before's.
void WarnControlsBeforeLog(PreparedFit& fit, int q, const mjModel& m, const std::string& where) {
  const FitSequence& sq = fit.sequences[q];
  const SampleGrid& g = fit.grids[q];
  const double dt = m.opt.timestep;
  auto ms = [](double seconds) { return FormatDigits(seconds * 1e3, 3) + " ms"; };
  std::vector<double> reach = sq.ctrl_delay;
  reach.resize(m.nu, 0.0);
  std::vector<std::string> fitted(m.nu);  // a fitted delay's description, per actuator
  for (int i = 0; i < m.nu; ++i) {
    const int v = fit.ctrl_delay_var[q][i];
    for (size_t c = 0; v >= 0 && c < fit.control_delays.size(); ++c) {
      if (fit.control_delay_index[c] != v) continue;
      const FitControlDelay& cd = fit.control_delays[c];
      const bool bounded = std::isfinite(cd.upper);
      reach[i] = bounded ? cd.upper : cd.initial;
      fitted[i] = cd.Name() + " (fitted, " + (bounded ? "up to its upper bound " : "from ") +
                  ms(reach[i]) + ")";
    }
  }
  int i = -1;
  const int steps = StepsBeforeFirstControl(g, sq.ctrl, reach, dt, &i);
  if (steps == 0 || i < 0) return;
  Eigen::Index j = 0;
  while (std::isnan(sq.ctrl(j, i))) ++j;
  const double t0 = sq.time.size() ? sq.time[0] : sq.x0.time;
  char at[96];
  std::snprintf(at, sizeof(at), " (at %.3f s, first sample at %.3f s)",
                t0 + g.ctrl_position[j] * dt, t0);
  const char* actuator = mj_id2name(&m, mjOBJ_ACTUATOR, i);
  const std::string who =
      m.nu > 1
          ? "actuator " + (actuator ? "'" + std::string(actuator) + "'" : std::to_string(i)) + ": "
          : "";
  const std::string cause = reach[i] > 0 ? "the control delay " +
                                               (fitted[i].empty() ? ms(reach[i]) : fitted[i]) +
                                               " reaches before the first logged command"
                                         : "the first logged command comes after the first sample";
  const bool zero = sq.ctrl_before == ControlBefore::kZero;
  fit.prepare_warnings.push_back(
      where + who + cause + at + ": " + (fitted[i].empty() ? "the first " : "up to the first ") +
      std::to_string(steps) + (steps == 1 ? " step uses" : " steps use") +
      " commands nobody logged (controls.before: " + ControlBeforeName(sq.ctrl_before) +
      (zero ? " gives them 0" : " holds the first one") +
      "; log the commands from before the first sample, or start the fit later)");
}

// 4e. sequence q's given initial state completed from the model (qpos0, rest) and stored as a
// physics vector
void SetInitialState(PreparedFit& fit, int q, const mjModel& m, const StateDims& d,
                     const std::string& where) {
  FitSequence& sq = fit.sequences[q];
  InitialState x0 = sq.x0;
  if (x0.qpos.size() == 0) x0.qpos = Eigen::Map<const Eigen::VectorXd>(m.qpos0, d.nq);
  if (x0.qvel.size() == 0) x0.qvel = Eigen::VectorXd::Zero(d.nv);
  if (x0.act.size() == 0) x0.act = Eigen::VectorXd::Zero(d.na);
  if (x0.qpos.size() != d.nq || x0.qvel.size() != d.nv || x0.act.size() != d.na) {
    throw std::invalid_argument(where + "initial state sizes differ from nq/nv/na");
  }
  fit.fixed_x0[q].resize(d.nphys);
  Eigen::Map<Eigen::VectorXd>(fit.fixed_x0[q].data(), d.nq) = x0.qpos;
  Eigen::Map<Eigen::VectorXd>(fit.fixed_x0[q].data() + d.nq, d.nv) = x0.qvel;
  Eigen::Map<Eigen::VectorXd>(fit.fixed_x0[q].data() + d.nq + d.nv, d.na) = x0.act;
  sq.x0 = x0;
}

// 4. every sequence: shapes, channels, controls, delays, its simulation grid, initial state and
// fitted states; then every fitted control delay and measurement term must be used somewhere
void PrepareSequences(PreparedFit& fit, FitVariables& vars, const FitOptions& options) {
  const size_t n = fit.sequences.size();
  fit.channels.assign(n, {});
  fit.fitted.assign(n, {});
  fit.fixed_x0.assign(n, {});
  fit.grids.assign(n, {});
  fit.missing.assign(n, {});
  fit.state_channels.assign(n, {});
  fit.state_missing.assign(n, {});
  fit.ctrl_delay_var.assign(n, {});
  fit.prepare_warnings.clear();
  std::vector<bool> delay_used(fit.control_delays.size(), false);
  for (size_t q = 0; q < n; ++q) {
    FitSequence& sq = fit.sequences[q];
    const FitModel& mo = fit.models[fit.ModelIndex(sq.model)];
    const StateDims& d = mo.sim->dims();
    const mjModel& m = mo.sim->model();
    const std::string where = "sequence '" + sq.name + "': ";
    const int iq = static_cast<int>(q);
    CheckSequenceShapes(sq, d, where);
    BuildChannels(fit, options, iq, where);
    CheckControls(sq, d.nu, where, &fit.prepare_warnings);
    AssignControlDelays(fit, iq, m, &delay_used);
    fit.grids[q] = BuildSampleGrid(
        sq.time, static_cast<int>(sq.measured.rows()), sq.x0.time, sq.ctrl, sq.ctrl_time,
        sq.ctrl_hold, vars.m.empty() ? sq.ctrl_delay : fit.ControlDelays(iq, vars.m.data()),
        m.opt.timestep, where, sq.ctrl_before);
    WarnControlsBeforeLog(fit, iq, m, where);
    SetInitialState(fit, iq, m, d, where);
    // logged states fitted as data (sysid/solve/state_residuals.h)
    if (options.states.any()) {
      fit.state_channels[q] = BuildStateChannels(m, options.states, "model '" + mo.name + "': ");
      fit.state_missing[q] = CheckLoggedStates(m, fit.state_channels[q],
                                               static_cast<int>(sq.measured.rows()), where, &sq);
    }
    // a sequence without a fitted column adds no residual: a mistake (a model without sensors, a
    // measured without columns, no_sensors without states), and a fit with no residual at all has
    // nothing to compute its uncertainty from
    if (fit.channels[q].empty() && fit.state_channels[q].empty()) {
      throw std::invalid_argument(
          where + "nothing to fit: no sensor column (measured is " +
          Shape(sq.measured.rows(), sq.measured.cols()) + ", model '" + mo.name + "' has " +
          std::to_string(m.nsensor) + " sensors" + (sq.no_sensors ? ", no_sensors is set" : "") +
          ") and no logged state fitted (FitOptions::states: qpos, qvel or act)");
    }
  }
  for (size_t c = 0; c < fit.control_delays.size(); ++c) {
    const FitControlDelay& cd = fit.control_delays[c];
    if (!delay_used[c]) {
      throw std::invalid_argument(
          "control delay '" + cd.Name() + "': " +
          (cd.actuator.empty()
               ? std::string("no sequence's model has an actuator")
               : "no sequence's model has an actuator named '" + cd.actuator + "'"));
    }
  }
  if (!fit.control_delays.empty() && options.states.any()) {
    throw std::invalid_argument(
        "a fitted control delay with fitted states (FitOptions::states) is not supported yet: "
        "give the delay, or fit the sensors alone");
  }
  for (const FitMeasurement& me : fit.measurements) {
    bool found = false;
    for (const auto& ch : fit.channels) {
      for (const auto& c : ch)
        found =
            found || (c.measurement >= 0 && fit.measurements[c.measurement].sensor == me.sensor);
    }
    if (!found) {
      throw std::invalid_argument("measurement terms for sensor '" + me.sensor +
                                  "', which no sequence fits");
    }
  }
}

// Switches off in sim what its nominal rollouts show can never change a simulated number
// (core/reduced_model.h); the simulator guards it.
void ReduceModel(const std::vector<Trajectory>& rollouts, Simulator* sim) {
  std::vector<const RowMatrix*> states;
  std::vector<const Eigen::VectorXd*> inputs;
  for (const Trajectory& tr : rollouts) {
    if (tr.T == 0) continue;
    states.push_back(&tr.states);
    inputs.push_back(&tr.inputs);
  }
  if (states.empty()) return;
  sim->SetReduction(AnalyzeReduction(sim->model(), sim->dims(), states, inputs));
}

// 5. the rollouts at the initial parameters (of the owned sequences: a sharded start) and their
// Jacobians, each model reduced; the fitted sensors that jump at contact events warned; per
// parameter whether it moves the data (fit.moves, checked here unless a sharded start combines it
// over the shards)
void InitialRollouts(PreparedFit& fit, FitVariables& vars, SolveContext& solve,
                     const FitOptions& options, FitPlan* out,
                     std::vector<Sensitivity>* initial_sensitivity) {
  std::vector<Trajectory>& initial = out->initial;
  initial.assign(fit.sequences.size(), Trajectory());
  initial_sensitivity->assign(fit.sequences.size(), Sensitivity());  // parameter columns
  std::vector<bool> moves(fit.params.size(), false);
  std::vector<double> work;
  for (size_t q = 0; q < fit.sequences.size(); ++q) {
    work.push_back(fit.SequenceWork(static_cast<int>(q)));
  }
  const std::vector<bool> owned =
      fit.owned_sequences ? fit.owned_sequences(work) : std::vector<bool>();
  // a share without sequences of a model still names the mode
  if (fit.owned_sequences) out->jacobian_mode = JacobianModeName(options.jacobian.mode);
  for (auto& mo : fit.models) {
    ApplyVariables(fit.params, mo.global, vars.z.data(), mo.sim.get());
    std::vector<SequenceInput> ins;
    std::vector<int> which;
    for (size_t q = 0; q < fit.sequences.size(); ++q) {
      if (fit.sequences[q].model != mo.name) continue;
      if (!owned.empty() && !owned[q]) continue;
      ins.push_back({fit.sequences[q].x0, fit.grids[q].ctrl});
      which.push_back(static_cast<int>(q));
    }
    if (ins.empty()) continue;
    if (options.observer) {
      long long steps = 0;
      for (const SequenceInput& in : ins) steps += static_cast<long long>(in.ctrl.rows());
      options.observer->OnStage(
          FitStage::kStart,
          (mo.sim->parameters().size() == 0 ? "rollout of " : "rollout and Jacobian of ") +
              std::to_string(ins.size()) + " sequence" + (ins.size() > 1 ? "s" : "") + ", " +
              std::to_string(steps) + " steps" +
              (fit.models.size() > 1 ? " (model " + mo.name + ")" : ""),
          SecondsSince(solve.fit_start));
    }
    std::vector<Trajectory> trs;
    JacobianOptions jo = options.jacobian;
    jo.zero_column_is_error = false;
    jo.state_jacobians = true;
    std::vector<Sensitivity> sens;
    const bool fitted_here = mo.sim->parameters().size() > 0;
    // the reduced model (what the rollouts show can never matter switched off) before the
    // Jacobian, whose perturbed steps it makes cheaper, unless there are fewer sequences than
    // threads: a rollout would then wait alone, and instead the columns follow the rollouts step
    // by step (core/simulator.h) and the model is reduced after
    const bool reduce_first =
        options.reduce_model && static_cast<int>(ins.size()) >= mo.sim->threads();
    if (fitted_here && !reduce_first) {
      mo.sim->RolloutAndJacobians(ins, jo, &trs, &sens);
    } else {
      mo.sim->Rollout(ins, &trs);
    }
    if (options.reduce_model) ReduceModel(trs, mo.sim.get());
    if (fitted_here && reduce_first) mo.sim->Jacobians(ins, trs, jo, &sens);
    // fitted sensors that jump at contact events (sysid/data/contact_channels.h)
    std::vector<std::string> fitted;
    for (int q : which) {
      for (const std::string& name : fit.fitted[q]) {
        if (std::find(fitted.begin(), fitted.end(), name) == fitted.end()) fitted.push_back(name);
      }
    }
    for (std::string& w : DiscontinuousChannelWarnings(mo.sim->model(), fitted, trs)) {
      fit.prepare_warnings.push_back((fit.models.size() > 1 ? "model '" + mo.name + "': " : "") +
                                     w);
    }
    for (size_t i = 0; i < which.size(); ++i) initial[which[i]] = std::move(trs[i]);
    if (!fitted_here) continue;
    for (const Sensitivity& s : sens) {
      for (int j = 0; j < mo.sim->parameters().size(); ++j) {
        if (!s.DxDp.col(j).isZero(0) || (s.DyDp.rows() && !s.DyDp.col(j).isZero(0))) {
          moves[mo.global[j]] = true;
        }
      }
    }
    out->jacobian_mode = JacobianModeName(sens.empty() ? jo.mode : sens[0].mode);
    for (size_t i = 0; i < which.size(); ++i) (*initial_sensitivity)[which[i]] = std::move(sens[i]);
  }
  // a sharded start leaves the check to its caller, with moves combined over every shard
  fit.moves = moves;
  if (!fit.owned_sequences) CheckParametersMove(fit, moves);
}

// 6. the segments (auto's horizon, sysid/solve/multiple_shooting.h) and their state blocks, started
// from the data where it determines the state; auto's contact segments leave out the sensors
// that jump and the cells next to contact events; the continuity weights
void BuildSegments(PreparedFit& fit, FitVariables& vars, SolveContext& solve,
                   const FitOptions& options, FitPlan* out) {
  std::vector<Trajectory>& initial = out->initial;
  fit.segments.clear();
  vars.states.clear();
  // auto under a sharded start (sysid/mpi/): every shard probes every sequence, as one process
  if (fit.owned_sequences && options.segment_steps < 0) RolloutUnowned(&fit, &initial);
  const HorizonChoice horizon = ChooseHorizon(fit, initial, options);
  out->segment_steps = horizon.steps;
  out->segments = SegmentRecord();
  out->segments.choice = horizon.reason;
  out->probe_rate = horizon.rate;
  out->probe_growth = horizon.growth;
  out->contact_segments = horizon.contacts;
  solve.stop_on_jacobian_warning = options.segment_steps < 0 && horizon.steps == 0;
  // a sharded start with free states (sysid/mpi/state_projection.h): every shard starts every
  // sequence's states from the data as one process does, so the other sequences are rolled out
  // at the initial values too (no Jacobians)
  if (fit.owned_sequences && (horizon.steps > 0 || options.estimate_initial_state)) {
    RolloutUnowned(&fit, &initial);
  }
  if (horizon.contacts && !options.fit_jumping_sensors) {
    for (std::string& w : OmitJumpingSensors(fit)) fit.prepare_warnings.push_back(std::move(w));
  }
  const EventWindowMask events =
      MaskEventWindows(fit, initial, horizon.contacts ? options.event_window : 0);
  if (events.masked > 0) {
    out->event_windows = {options.event_window, events.events, events.masked, events.sensors};
    fit.prepare_warnings.push_back(events.Summary());
  }
  for (size_t q = 0; q < fit.sequences.size(); ++q) {
    const int T = fit.grids[q].steps;  // simulation steps
    const int len = horizon.steps > 0 ? horizon.steps : T;
    const size_t first = fit.segments.size();
    for (int k0 = 0; k0 < T; k0 += len) {
      Segment seg;
      seg.seq = static_cast<int>(q);
      seg.model = fit.ModelIndex(fit.sequences[q].model);
      seg.k0 = k0;
      seg.T = std::min(len, T - k0);
      seg.state_rows = !fit.state_channels[q].empty();
      const bool free = k0 > 0 || options.estimate_initial_state;
      // RolloutUnowned above simulated every sequence a free state starts from
      MJSYSID_DEMAND(!free || initial[q].states.rows() > 0,
                     "a free state without its start rollout");
      if (free) {
        seg.block = static_cast<int>(vars.states.size());
        std::vector<double> x;
        if (k0 == 0) {
          // the sequence's given x0 (the estimate's start)
          const auto row = initial[q].states.row(0);
          x.assign(row.data(), row.data() + row.size());
        } else {
          // later segments from the data where they determine the state, else the rollout
          out->segments.start_source = SegmentStart(fit, static_cast<int>(q), k0, initial[q], &x);
        }
        vars.states.push_back(std::move(x));
      }
      fit.segments.push_back(seg);
    }
    for (size_t s = first; s + 1 < fit.segments.size(); ++s) {
      fit.segments[s].next = fit.segments[s + 1].block;
    }
  }
  // the continuity rows' weights, scaled to the sensors (sysid/solve/multiple_shooting.h)
  bool joined = false;
  for (const Segment& seg : fit.segments) joined = joined || seg.next >= 0;
  std::string weights;
  fit.continuity_weights = ContinuityWeights(fit, initial, options, &weights);
  if (joined) out->segments.weights = weights;
}

// 7. the evaluation cache, seeded with the initial rollouts (and Jacobians) of whole sequences
void SeedCache(PreparedFit& fit, FitVariables& vars, SolveContext& solve, const FitOptions& options,
               std::vector<Trajectory>& initial, std::vector<Sensitivity>& initial_sensitivity) {
  std::vector<EvaluationCache::Model> simulated;
  for (const FitModel& mo : fit.models) simulated.push_back({mo.sim.get(), mo.global});
  solve.cache = std::make_unique<EvaluationCache>(std::move(simulated), &fit.params, &fit.sequences,
                                                  &fit.segments, options.jacobian, &fit.grids);
  for (size_t s = 0; s < fit.segments.size(); ++s) {
    const Segment& seg = fit.segments[s];
    if (seg.block >= 0 || seg.next >= 0 || seg.T != initial[seg.seq].T) continue;
    solve.cache->Seed(static_cast<int>(s), vars.z.empty() ? nullptr : vars.z.data(),
                      fit.X0(vars.states, static_cast<int>(s)), initial[seg.seq],
                      std::move(initial_sensitivity[seg.seq]));
  }
}

}  // namespace

std::vector<int> ControlDelayOfActuators(const std::vector<FitControlDelay>& delays,
                                         const mjModel& m) {
  std::vector<int> follows(static_cast<size_t>(m.nu), -1);
  for (int i = 0; i < m.nu; ++i) {
    const char* actuator = mj_id2name(&m, mjOBJ_ACTUATOR, i);
    int shared = -1, own = -1;
    for (size_t c = 0; c < delays.size(); ++c) {
      const std::string& name = delays[c].actuator;
      if (name.empty()) shared = static_cast<int>(c);
      if (!name.empty() && actuator && name == actuator) own = static_cast<int>(c);
    }
    follows[static_cast<size_t>(i)] = own >= 0 ? own : shared;
  }
  return follows;
}

void CheckHeldOutSequence(const FitSequence& sq, const mjModel& m, const std::string& where) {
  const StateDims d(m);
  CheckSequenceShapes(sq, d, where);
  std::vector<std::string> warnings;  // held NaN controls: the simulation holds them, as a fit's
  CheckControls(sq, d.nu, where, &warnings);
  BuildSampleGrid(sq.time, static_cast<int>(sq.measured.rows()), sq.x0.time, sq.ctrl, sq.ctrl_time,
                  sq.ctrl_hold, sq.ctrl_delay, m.opt.timestep, where, sq.ctrl_before);
}

FitPlan PrepareFit(const FitParts& parts, const FitOptions& options) {
  PreparedFit& fit = *parts.fit;
  FitVariables& vars = *parts.vars;
  SolveContext& solve = *parts.solve;
  FitPlan plan;
  solve.cache.reset();  // it borrows the simulators rebuilt below
  fit.options = options;
  RestoreEventWindows(fit);  // a previous fit's event windows (sysid/data/event_windows.h)
  if (fit.models.empty()) throw std::invalid_argument("no model: call AddModel first");
  if (fit.sequences.empty()) throw std::invalid_argument("no sequence: call AddSequence first");
  CheckParameters(fit);
  BuildSimulators(fit, vars, solve, options);
  BuildTermVariables(fit, vars, &plan);
  // something must be estimated (as an experiment file's "no parameters to identify"); the
  // initial states alone are an estimate
  if (fit.params.empty() && vars.m.empty() && !options.estimate_initial_state) {
    throw std::invalid_argument(
        "nothing to estimate: no parameter (AddParameter), no fitted measurement term or control "
        "delay (AddMeasurement, AddControlDelay) and estimate_initial_state is off");
  }
  PrepareSequences(fit, vars, options);
  std::vector<Sensitivity> initial_sensitivity;
  InitialRollouts(fit, vars, solve, options, &plan, &initial_sensitivity);
  BuildSegments(fit, vars, solve, options, &plan);
  SeedCache(fit, vars, solve, options, plan.initial, initial_sensitivity);
  return plan;
}

}  // namespace mjsysid
