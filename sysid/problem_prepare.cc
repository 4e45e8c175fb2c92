// Problem::Prepare: validates the inputs (names, shapes, bounds, the data that every parameter
// must move) and builds what a fit runs on: the simulators with their parameters, the variables,
// the sample grids (with the fitted control delays applied to the held controls), the segments
// of single or multiple shooting (the auto horizon, sysid/multiple_shooting.h), the initial
// rollouts and Jacobians and the evaluation cache (Problem::Impl, sysid/problem_impl.h).
// Fit and CheckJacobians (sysid/problem.cc) run on the result.
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
#include <vector>

#include "core/text.h"
#include "sysid/contact_channels.h"
#include "sysid/cost_functions.h"
#include "sysid/derived_inertials.h"
#include "sysid/equation_error.h"
#include "sysid/evaluation_cache.h"
#include "sysid/event_windows.h"
#include "sysid/fit_status.h"
#include "sysid/interval_check.h"
#include "sysid/multiple_shooting.h"
#include "sysid/problem.h"
#include "sysid/problem_impl.h"
#include "sysid/progress.h"
#include "sysid/residual_model.h"
#include "sysid/state_manifold.h"
#include "sysid/state_residuals.h"
#include "sysid/variable_manifold.h"

namespace mjsysid {

// -----------------------------------------------------------------------------------------------
// fitted control delays

std::vector<double> Problem::Impl::ControlDelays(int q, const double* mv, int shifted,
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

void Problem::Impl::SyncControlDelays(int q, const double* mv) {
  if (mv == nullptr || !HasControlDelay(q)) return;
  SampleGrid& grid = grids[q];
  const std::vector<double> delay = ControlDelays(q, mv);
  if (delay == grid.delay) return;
  const FitSequence& sq = sequences[q];
  const double dt = models[ModelIndex(sq.model)].sim->model().opt.timestep;
  HoldControls(grid, sq.ctrl, sq.ctrl_hold, delay, dt, &grid.ctrl);
  grid.delay = delay;
  ++cost_inputs_epoch;  // the cost functions read the controls
}

// -----------------------------------------------------------------------------------------------
// building

void CheckParametersMove(const Problem::Impl& I, const std::vector<bool>& moves) {
  for (size_t g = 0; g < I.params.size(); ++g) {
    if (g >= moves.size() || !moves[g]) {
      throw ParameterError("parameter '" + I.params[g].name +
                           "' has no effect on the simulated states or sensors of any sequence "
                           "(its Jacobian column is exactly zero): remove it or add data that "
                           "excites it");
    }
  }
}

// Switches off in sim what its nominal rollouts show can never change a simulated number
// (core/reduced_model.h); the simulator guards it.
static void ReduceModel(const std::vector<Trajectory>& rollouts, Simulator* sim) {
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

void Problem::Prepare(const FitOptions& options, Prepared* out) {
  Impl& I = *impl_;
  I.cache.reset();  // it borrows the simulators rebuilt below
  I.options = options;
  RestoreEventWindows(I);  // a previous fit's event windows (sysid/event_windows.h)
  if (I.models.empty()) throw std::invalid_argument("no model: call AddModel first");
  if (I.sequences.empty()) throw std::invalid_argument("no sequence: call AddSequence first");
  std::vector<Trajectory>& initial = out->initial;
  std::vector<std::string>& names = out->names;
  std::vector<std::pair<double, double>>& mbounds = out->mbounds;
  const int np = static_cast<int>(I.params.size());

  // parameters: bounds, transforms, initial values
  for (int g = 0; g < np; ++g) {
    const FitParameter& p = I.params[g];
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
    for (const std::string& mname : p.models) I.ModelIndex(mname);
  }

  // simulators: each model with the parameters that apply to it
  SimulatorOptions so;
  so.threads = options.threads;
  for (auto& mo : I.models) {
    std::vector<ParameterSpec> specs;
    mo.global.clear();
    for (int g = 0; g < np; ++g) {
      const FitParameter& p = I.params[g];
      if (!p.models.empty() &&
          std::find(p.models.begin(), p.models.end(), mo.name) == p.models.end()) {
        continue;
      }
      ParameterSpec spec = p.target;
      spec.label = p.name;
      specs.push_back(spec);
      mo.global.push_back(g);
    }
    try {
      mo.sim = std::make_unique<Simulator>(*mo.model, specs, so);
    } catch (const ParameterError& e) {
      throw ParameterError("model '" + mo.name + "': " + e.what());
    }
    mo.manifold = std::make_unique<StateManifold>(&mo.sim->model());
    mo.sim->SetStepProgress(options.verbose ? I.step_progress.get() : nullptr);
  }
  I.z.resize(np);
  for (int g = 0; g < np; ++g) I.z[g] = I.ToZ(g, I.params[g].initial);

  // measurement terms
  I.m.clear();
  I.term_index.assign(I.measurements.size(), TermIndex());
  names.clear();
  for (int g = 0; g < np; ++g) names.push_back(I.params[g].name);
  mbounds.clear();
  out->minitial.clear();
  for (size_t i = 0; i < I.measurements.size(); ++i) {
    const FitMeasurement& me = I.measurements[i];
    auto add = [&](const FitMeasurement::Term& t, int* index, const char* what) {
      if (!t.fit) return;
      if (t.initial < t.lower || t.initial > t.upper) {
        throw std::invalid_argument("measurement " + std::string(what) + " of sensor '" +
                                    me.sensor + "': initial value outside its bounds");
      }
      *index = static_cast<int>(I.m.size());
      I.m.push_back(t.initial);
      mbounds.emplace_back(t.lower, t.upper);
      out->minitial.push_back(t.initial);
      names.push_back(me.sensor + "." + what);
    };
    add(me.delay, &I.term_index[i].delay, "delay");
    add(me.gain, &I.term_index[i].gain, "gain");
    add(me.bias, &I.term_index[i].bias, "bias");
  }

  // fitted control delays, appended to the m block (seconds, >= 0)
  I.control_delay_index.clear();
  for (const FitControlDelay& cd : I.control_delays) {
    const std::string where = "control delay '" + cd.Name() + "': ";
    if (!std::isfinite(cd.initial)) throw std::invalid_argument(where + "initial value not finite");
    if (!(cd.lower >= 0)) throw std::invalid_argument(where + "lower bound must be >= 0 (seconds)");
    if (!(cd.lower < cd.upper)) throw std::invalid_argument(where + "lower bound >= upper bound");
    if (cd.initial < cd.lower || cd.initial > cd.upper) {
      throw std::invalid_argument(where + "initial value " + FormatDigits(cd.initial, 6) +
                                  " outside its bounds");
    }
    I.control_delay_index.push_back(static_cast<int>(I.m.size()));
    I.m.push_back(cd.initial);
    mbounds.emplace_back(cd.lower, cd.upper);
    out->minitial.push_back(cd.initial);
    names.push_back(cd.Name());
  }
  std::vector<bool> delay_used(I.control_delays.size(), false);

  // sequences: shapes, channels, missing samples, the simulation grid
  I.channels.assign(I.sequences.size(), {});
  I.fitted.assign(I.sequences.size(), {});
  I.fixed_x0.assign(I.sequences.size(), {});
  I.grids.assign(I.sequences.size(), {});
  I.missing.assign(I.sequences.size(), {});
  I.state_channels.assign(I.sequences.size(), {});
  I.state_missing.assign(I.sequences.size(), {});
  I.ctrl_delay_var.assign(I.sequences.size(), {});
  I.prepare_warnings.clear();
  for (size_t q = 0; q < I.sequences.size(); ++q) {
    FitSequence& sq = I.sequences[q];
    const Impl::Model& mo = I.models[I.ModelIndex(sq.model)];
    const StateDims& d = mo.sim->dims();
    const std::string where = "sequence '" + sq.name + "': ";
    const int T = static_cast<int>(sq.measured.rows());
    const int Tc = static_cast<int>(sq.ctrl_time.size() ? sq.ctrl_time.size() : T);
    if (T < 1 || sq.measured.cols() != d.ns) {
      throw std::invalid_argument(where + "measured must be T x " + std::to_string(d.ns) +
                                  " (T x nsensordata, T >= 1), got " +
                                  std::to_string(sq.measured.rows()) + " x " +
                                  std::to_string(sq.measured.cols()));
    }
    if (sq.ctrl.rows() != Tc || sq.ctrl.cols() != d.nu) {
      throw std::invalid_argument(
          where + "ctrl must be " + std::to_string(Tc) + " x nu with nu = " + std::to_string(d.nu) +
          " (" + (sq.ctrl_time.size() ? "one row per ctrl_time" : "T x nu") + "), got " +
          std::to_string(sq.ctrl.rows()) + " x " + std::to_string(sq.ctrl.cols()));
    }
    if (sq.time.size() != 0 && sq.time.size() != T) {
      throw std::invalid_argument(where + "time must be empty or have " + std::to_string(T) +
                                  " entries, got " + std::to_string(sq.time.size()));
    }
    if ((!sq.ctrl_hold.empty() && static_cast<int>(sq.ctrl_hold.size()) != d.nu) ||
        (!sq.ctrl_delay.empty() && static_cast<int>(sq.ctrl_delay.size()) != d.nu)) {
      throw std::invalid_argument(where + "ctrl_hold and ctrl_delay need one entry per actuator");
    }
    for (double delay : sq.ctrl_delay) {
      if (!(delay >= 0) || !std::isfinite(delay)) {
        throw std::invalid_argument(where + "a control delay must be finite and >= 0");
      }
    }
    const mjModel& m = mo.sim->model();
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
      for (size_t i = 0; i < I.measurements.size(); ++i) {
        if (I.measurements[i].sensor == sname) meas = static_cast<int>(i);
      }
      // NaN: not measured (masked, counted); Inf: an error; a column with nothing left: an error
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
        I.channels[q].push_back({col, weight, meas});
        I.missing[q].push_back(missing);
      }
      if (std::find(I.fitted[q].begin(), I.fitted[q].end(), sname) == I.fitted[q].end()) {
        I.fitted[q].push_back(sname);
      }
    }
    // controls: Inf is an error; NaN is held from the last valid value (warned), an error before
    // the first one
    std::string held;
    int held_rows = 0;
    for (int i = 0; i < d.nu; ++i) {
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
      I.prepare_warnings.push_back(where + std::to_string(held_rows) +
                                   " NaN control value(s) held from the last valid " +
                                   "one (rows " + held + (held_rows > 5 ? ", ..." : "") + ")");
    }
    // the fitted control delay each actuator follows (its own, else the shared one), if any
    I.ctrl_delay_var[q].assign(d.nu, -1);
    for (int i = 0; i < d.nu; ++i) {
      const char* actuator = mj_id2name(&m, mjOBJ_ACTUATOR, i);
      int shared = -1, own = -1;
      for (size_t c = 0; c < I.control_delays.size(); ++c) {
        const std::string& name = I.control_delays[c].actuator;
        if (name.empty()) shared = static_cast<int>(c);
        if (!name.empty() && actuator && name == actuator) own = static_cast<int>(c);
      }
      const int c = own >= 0 ? own : shared;
      if (c < 0) continue;
      I.ctrl_delay_var[q][i] = I.control_delay_index[c];
      delay_used[c] = true;
    }
    I.grids[q] = BuildSampleGrid(sq.time, T, sq.x0.time, sq.ctrl, sq.ctrl_time, sq.ctrl_hold,
                                 I.m.empty() ? sq.ctrl_delay : I.ControlDelays(q, I.m.data()),
                                 m.opt.timestep, where);
    // the given initial state as a physics vector
    InitialState x0 = sq.x0;
    if (x0.qpos.size() == 0) x0.qpos = Eigen::Map<const Eigen::VectorXd>(m.qpos0, d.nq);
    if (x0.qvel.size() == 0) x0.qvel = Eigen::VectorXd::Zero(d.nv);
    if (x0.act.size() == 0) x0.act = Eigen::VectorXd::Zero(d.na);
    if (x0.qpos.size() != d.nq || x0.qvel.size() != d.nv || x0.act.size() != d.na) {
      throw std::invalid_argument(where + "initial state sizes differ from nq/nv/na");
    }
    I.fixed_x0[q].resize(d.nphys);
    Eigen::Map<Eigen::VectorXd>(I.fixed_x0[q].data(), d.nq) = x0.qpos;
    Eigen::Map<Eigen::VectorXd>(I.fixed_x0[q].data() + d.nq, d.nv) = x0.qvel;
    Eigen::Map<Eigen::VectorXd>(I.fixed_x0[q].data() + d.nq + d.nv, d.na) = x0.act;
    sq.x0 = x0;
    // logged states fitted as data (sysid/state_residuals.h)
    if (options.states.any()) {
      I.state_channels[q] = BuildStateChannels(m, options.states, "model '" + mo.name + "': ");
      I.state_missing[q] = CheckLoggedStates(m, I.state_channels[q], T, where, &sq);
    }
  }
  for (size_t c = 0; c < I.control_delays.size(); ++c) {
    const FitControlDelay& cd = I.control_delays[c];
    if (!delay_used[c]) {
      throw std::invalid_argument(
          "control delay '" + cd.Name() + "': " +
          (cd.actuator.empty()
               ? std::string("no sequence's model has an actuator")
               : "no sequence's model has an actuator named '" + cd.actuator + "'"));
    }
  }
  if (!I.control_delays.empty() && options.states.any()) {
    throw std::invalid_argument(
        "a fitted control delay with fitted states (FitOptions::states) is not supported yet: "
        "give the delay, or fit the sensors alone");
  }
  for (const FitMeasurement& me : I.measurements) {
    bool found = false;
    for (const auto& ch : I.channels) {
      for (const auto& c : ch)
        found = found || (c.measurement >= 0 && I.measurements[c.measurement].sensor == me.sensor);
    }
    if (!found) {
      throw std::invalid_argument("measurement terms for sensor '" + me.sensor +
                                  "', which no sequence fits");
    }
  }

  // initial rollouts at the initial parameters (of the owned sequences: a sharded start); the
  // Jacobian there must see every parameter
  initial.assign(I.sequences.size(), Trajectory());
  std::vector<Sensitivity> initial_sensitivity(I.sequences.size());  // parameter columns
  std::vector<bool> moves(np, false);
  const std::vector<bool> owned = I.owned_sequences ? I.owned_sequences(I) : std::vector<bool>();
  // a share without sequences of a model still names the mode
  if (I.owned_sequences) out->jacobian_mode = JacobianModeName(options.jacobian.mode);
  for (auto& mo : I.models) {
    ApplyVariables(I.params, mo.global, I.z.data(), mo.sim.get());
    std::vector<SequenceInput> ins;
    std::vector<int> which;
    for (size_t q = 0; q < I.sequences.size(); ++q) {
      if (I.sequences[q].model != mo.name) continue;
      if (!owned.empty() && !owned[q]) continue;
      ins.push_back({I.sequences[q].x0, I.grids[q].ctrl});
      which.push_back(static_cast<int>(q));
    }
    if (ins.empty()) continue;
    if (options.verbose) {
      long long steps = 0;
      for (const SequenceInput& in : ins) steps += static_cast<long long>(in.ctrl.rows());
      PrintFitProgress(
          "start",
          (mo.sim->parameters().size() == 0 ? "rollout of " : "rollout and Jacobian of ") +
              std::to_string(ins.size()) + " sequence" + (ins.size() > 1 ? "s" : "") + ", " +
              std::to_string(steps) + " steps" +
              (I.models.size() > 1 ? " (model " + mo.name + ")" : ""),
          I.fit_start);
    }
    std::vector<Trajectory> trs;
    JacobianOptions jo = options.jacobian;
    jo.zero_column_is_error = false;
    jo.state_jacobians = true;
    std::vector<Sensitivity> sens;
    const bool fitted_here = mo.sim->parameters().size() > 0;
    // the reduced model (what the rollouts show can never matter switched off) before the
    // Jacobian, whose perturbed steps it makes cheaper (arm7: 33 -> 27 ms a rollout), unless
    // there are fewer sequences than threads: a rollout would then wait alone, and instead the
    // columns follow the rollouts step by step (core/simulator.h) and the model is reduced after
    const bool reduce_first =
        options.reduce_model && static_cast<int>(ins.size()) >= mo.sim->threads();
    if (fitted_here && !reduce_first) {
      mo.sim->RolloutAndJacobians(ins, jo, &trs, &sens);
    } else {
      mo.sim->Rollout(ins, &trs);
    }
    if (options.reduce_model) ReduceModel(trs, mo.sim.get());
    if (fitted_here && reduce_first) mo.sim->Jacobians(ins, trs, jo, &sens);
    // fitted sensors that jump at contact events (sysid/contact_channels.h)
    std::vector<std::string> fitted;
    for (int q : which) {
      for (const std::string& name : I.fitted[q]) {
        if (std::find(fitted.begin(), fitted.end(), name) == fitted.end()) fitted.push_back(name);
      }
    }
    for (std::string& w : DiscontinuousChannelWarnings(mo.sim->model(), fitted, trs)) {
      I.prepare_warnings.push_back((I.models.size() > 1 ? "model '" + mo.name + "': " : "") + w);
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
    for (size_t i = 0; i < which.size(); ++i) initial_sensitivity[which[i]] = std::move(sens[i]);
  }
  // a sharded start leaves the check to its caller, with moves combined over every shard
  I.moves = moves;
  if (!I.owned_sequences) CheckParametersMove(I, moves);

  // segments (multiple shooting) and state blocks
  I.segments.clear();
  I.states.clear();
  // auto under a sharded start (sysid/mpi/): every shard probes every sequence, as one process
  if (I.owned_sequences && options.segment_steps < 0) RolloutUnowned(&I, &initial);
  const HorizonChoice horizon = ChooseHorizon(I, initial, options);
  out->segment_steps = horizon.steps;
  out->segment_reason = horizon.reason;
  out->probe_rate = horizon.rate;
  out->probe_growth = horizon.growth;
  out->contact_segments = horizon.contacts;
  I.stop_on_jacobian_warning = options.segment_steps < 0 && horizon.steps == 0;
  // a sharded start with free states (sysid/mpi/state_projection.h): every shard starts every
  // sequence's states from the data as one process does, so the other sequences are rolled out
  // at the initial values too (no Jacobians)
  if (I.owned_sequences && (horizon.steps > 0 || options.estimate_initial_state)) {
    RolloutUnowned(&I, &initial);
  }
  // auto's contact segments: the sensors that jump at contact events left out, saying so
  if (horizon.contacts && !options.fit_jumping_sensors) {
    for (std::string& w : OmitJumpingSensors(I)) I.prepare_warnings.push_back(std::move(w));
  }
  // auto's contact segments: the velocity- and acceleration-level cells next to contact events
  // left out, saying so (sysid/event_windows.h)
  const EventWindowMask events =
      MaskEventWindows(I, initial, horizon.contacts ? options.event_window : 0);
  if (events.masked > 0) {
    out->event_windows = {options.event_window, events.events, events.masked, events.sensors};
    I.prepare_warnings.push_back(events.Summary());
  }
  std::string start_source;
  for (size_t q = 0; q < I.sequences.size(); ++q) {
    const int T = I.grids[q].steps;  // simulation steps
    const int len = horizon.steps > 0 ? horizon.steps : T;
    const size_t first = I.segments.size();
    for (int k0 = 0; k0 < T; k0 += len) {
      Segment seg;
      seg.seq = static_cast<int>(q);
      seg.model = I.ModelIndex(I.sequences[q].model);
      seg.k0 = k0;
      seg.T = std::min(len, T - k0);
      seg.state_rows = !I.state_channels[q].empty();
      const bool free = k0 > 0 || options.estimate_initial_state;
      if (free && initial[q].states.rows() == 0) {
        std::fprintf(stderr, "sysid: broken invariant: a free state without its start rollout\n");
        std::abort();  // RolloutUnowned above simulated every sequence
      }
      if (free) {
        seg.block = static_cast<int>(I.states.size());
        std::vector<double> x;
        if (k0 == 0) {
          // the sequence's given x0 (the estimate's start)
          const auto row = initial[q].states.row(0);
          x.assign(row.data(), row.data() + row.size());
        } else {
          // later segments from the data where they determine the state, else the rollout
          start_source = SegmentStart(I, static_cast<int>(q), k0, initial[q], &x);
        }
        I.states.push_back(std::move(x));
      }
      I.segments.push_back(seg);
    }
    for (size_t s = first; s + 1 < I.segments.size(); ++s) {
      I.segments[s].next = I.segments[s + 1].block;
    }
  }

  if (!start_source.empty()) out->segment_reason += "; segment states from " + start_source;
  // the continuity rows' weights, scaled to the sensors (sysid/multiple_shooting.h)
  bool joined = false;
  for (const Segment& seg : I.segments) joined = joined || seg.next >= 0;
  std::string weights;
  I.continuity_weights = ContinuityWeights(I, initial, options, &weights);
  if (joined) out->segment_reason += "; " + weights;

  // evaluation cache, seeded with the initial rollouts (and Jacobians) of whole sequences
  std::vector<EvaluationCache::Model> simulated;
  for (const Impl::Model& mo : I.models) simulated.push_back({mo.sim.get(), mo.global});
  I.cache = std::make_unique<EvaluationCache>(std::move(simulated), &I.params, &I.sequences,
                                              &I.segments, options.jacobian, &I.grids);
  for (size_t s = 0; s < I.segments.size(); ++s) {
    const Segment& seg = I.segments[s];
    if (seg.block >= 0 || seg.next >= 0 || seg.T != initial[seg.seq].T) continue;
    I.cache->Seed(static_cast<int>(s), I.z.empty() ? nullptr : I.z.data(),
                  I.X0(static_cast<int>(s)), initial[seg.seq],
                  std::move(initial_sensitivity[seg.seq]));
  }
}

}  // namespace mjsysid
