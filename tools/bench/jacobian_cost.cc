// bench_jacobian_cost: the cost of one Jacobian column in units of one nominal mj_step, per
// parameter kind and per Jacobian mode (issue 3).
//
// For every model and every parameter kind that applies to it, a single-thread Simulator with
// exactly that one parameter times Simulator::Jacobians in the directional, matrix and
// whole-rollout modes, with forward and central differences:
//   cost per column [steps] = Jacobian time / (T * nominal step time),
// with the nominal step time = Simulator::Rollout time / T of the same Simulator, timed right
// before each timed Jacobian; the cost is the median over repeats of the ratio of the two.
// Matrix mode also pays mjd_transitionFD (2nv+na state columns) once per time step for all
// parameter columns together, so two more rows isolate the marginal cost of one parameter column:
// - matrix_marginal: matrix mode with 2 parameters of the same kind (on two objects) minus matrix
//   mode with 1 parameter, median of the paired differences of interleaved runs;
// - skip_step: the perturbed step that matrix mode takes per parameter (mj_setState + StepSkip
//   from the parameter's stage, after a full mj_forward at x_k), as the difference of two loops
//   over the trajectory, with and without it.
// Each row also shows the Simulator's own estimate, JacobianCostPerStep. Wall clock
// (std::chrono::steady_clock) unless --clock cpu; the table goes to stdout and, with --csv, to a
// CSV file.
#include <CLI/CLI.hpp>
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <ctime>
#include <exception>
#include <fstream>
#include <functional>
#include <sstream>
#include <string>
#include <vector>

#include "core/mujoco_env.h"
#include "core/parameters.h"
#include "core/simulator.h"
#include "core/state.h"
#include "mjsysid/version.h"

namespace mjsysid {
namespace {

// the clock of every measurement: wall time (steady_clock, the default) or, with --clock cpu, the
// CPU time of this process (robust to other processes on a busy machine; threads = 1)
bool cpu_clock = false;

double Now() {
  if (cpu_clock) {
    timespec ts;
    clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &ts);
    return static_cast<double>(ts.tv_sec) + 1e-9 * static_cast<double>(ts.tv_nsec);
  }
  return std::chrono::duration<double>(std::chrono::steady_clock::now().time_since_epoch()).count();
}

double SecondsSince(double t0) { return Now() - t0; }

// the 1-minute load average (other processes competing for the cores), or -1
double LoadAverage() {
  std::ifstream in("/proc/loadavg");
  double load = -1;
  in >> load;
  return load;
}

double Median(std::vector<double> v) {
  if (v.empty()) return NAN;
  std::sort(v.begin(), v.end());
  const size_t n = v.size();
  return n % 2 ? v[n / 2] : 0.5 * (v[n / 2 - 1] + v[n / 2]);
}

// time of fn on the selected clock, median over repeats (after warmup untimed calls)
double TimeMedian(int repeats, int warmup, const std::function<void()>& fn) {
  for (int i = 0; i < warmup; ++i) fn();
  std::vector<double> t;
  for (int i = 0; i < repeats; ++i) {
    const double t0 = Now();
    fn();
    t.push_back(SecondsSince(t0));
  }
  return Median(t);
}

std::vector<std::string> Split(const std::string& s, char sep) {
  std::vector<std::string> out;
  std::stringstream in(s);
  std::string item;
  while (std::getline(in, item, sep)) {
    if (!item.empty()) out.push_back(item);
  }
  return out;
}

// which objects each parameter kind uses in one model: two of each type (the second one only
// for the matrix-mode marginal), and the number of samples of the benchmark rollout
struct ModelCase {
  std::string name;
  int T = 500;
  std::string body[2], joint[2], geom[2], actuator[2];  // geom empty: no geom_friction
  std::string tendon[2];                                // empty: no tendon kinds
  std::string servo[2];          // position/velocity servos or pids: the servo gain kinds
  std::string inertial_body[2];  // bodies with a strictly consistent inertial: body_inertial
  std::string dcmotor[2];        // <dcmotor>s with an inductance: the dcmotor kinds
  std::string pair[2];           // explicit contact pairs: the pair kinds
  std::string pid[2];            // pid actuators: actuator_ki
  std::string delayed_actuator[2], delayed_sensor[2];  // linear history buffers: the delay kinds
};

ModelCase CaseFor(const std::string& name, const mjModel& m, bool quick) {
  ModelCase c;
  c.name = name;
  if (name == "arm5") {
    c.T = quick ? 300 : 1000;
    c.body[0] = "link3", c.body[1] = "link4";
    c.joint[0] = "j3", c.joint[1] = "j4";
    c.actuator[0] = "m3", c.actuator[1] = "m4";
    return c;
  }
  if (name == "humanoid") {
    c.T = quick ? 100 : 200;
    c.body[0] = "thigh_right", c.body[1] = "thigh_left";
    c.joint[0] = "knee_right", c.joint[1] = "knee_left";
    c.geom[0] = "foot_right", c.geom[1] = "foot_left";
    c.actuator[0] = "knee_right", c.actuator[1] = "knee_left";
    return c;
  }
  if (name == "arm7") {
    c.T = quick ? 300 : 1000;
    c.body[0] = "link5", c.body[1] = "link6";
    c.joint[0] = "j5", c.joint[1] = "j6";
    c.servo[0] = "s5", c.servo[1] = "s6";
    c.inertial_body[0] = "link6", c.inertial_body[1] = "link7";
    return c;
  }
  // any other model: the first two named bodies with mass, hinge/slide joints and actuators
  c.T = quick ? 200 : 500;
  auto pick = [&](mjtObj type, int n, const std::function<bool(int)>& ok, std::string* out) {
    int found = 0;
    for (int i = 0; i < n && found < 2; ++i) {
      const char* s = mj_id2name(&m, type, i);
      if (s && s[0] && ok(i)) out[found++] = s;
    }
    if (found < 2) out[0].clear();
  };
  pick(
      mjOBJ_BODY, static_cast<int>(m.nbody), [&](int i) { return i > 0 && m.body_mass[i] > 0; },
      c.body);
  pick(
      mjOBJ_JOINT, static_cast<int>(m.njnt),
      [&](int i) { return m.jnt_type[i] == mjJNT_HINGE || m.jnt_type[i] == mjJNT_SLIDE; }, c.joint);
  pick(
      mjOBJ_ACTUATOR, static_cast<int>(m.nactuator), [&](int) { return true; }, c.actuator);
  pick(
      mjOBJ_TENDON, static_cast<int>(m.ntendon), [&](int) { return true; }, c.tendon);
  pick(
      mjOBJ_ACTUATOR, static_cast<int>(m.nactuator),
      [&](int i) {
        // pids and position servos (both have kp and kv)
        return m.actuator_gaintype[i] == mjGAIN_PID || (m.actuator_biastype[i] == mjBIAS_AFFINE &&
                                                        m.actuator_biasprm[mjNBIAS * i + 1] != 0);
      },
      c.servo);
  pick(
      mjOBJ_ACTUATOR, static_cast<int>(m.nactuator),
      [&](int i) {
        return m.actuator_gaintype[i] == mjGAIN_DCMOTOR && m.actuator_dynprm[mjNDYN * i] > 0;
      },
      c.dcmotor);
  pick(
      mjOBJ_PAIR, static_cast<int>(m.npair), [&](int) { return true; }, c.pair);
  pick(
      mjOBJ_ACTUATOR, static_cast<int>(m.nactuator),
      [&](int i) { return m.actuator_gaintype[i] == mjGAIN_PID; }, c.pid);
  // delays: a history buffer with linear interpolation (the delay kinds' requirement)
  pick(
      mjOBJ_ACTUATOR, static_cast<int>(m.nactuator),
      [&](int i) { return m.actuator_historyadr[i] >= 0 && m.actuator_history[2 * i + 1] == 1; },
      c.delayed_actuator);
  pick(
      mjOBJ_SENSOR, static_cast<int>(m.nsensor),
      [&](int i) { return m.sensor_historyadr[i] >= 0 && m.sensor_history[2 * i + 1] == 1; },
      c.delayed_sensor);
  return c;
}

// one parameter kind on two objects, with its component index
struct KindCase {
  std::string kind;
  std::string object[2];
  int index = 0;
};

std::vector<KindCase> KindsFor(const ModelCase& c) {
  std::vector<KindCase> kinds;
  auto add = [&](const char* kind, const std::string* objects, int index) {
    if (objects[0].empty()) return;
    kinds.push_back({kind, {objects[0], objects[1]}, index});
  };
  add("body_mass", c.body, 0);
  add("body_mass_inertia", c.body, 0);
  add("body_inertia", c.body, 1);  // about y: the pitch axis of both shipped models
  add("body_com", c.body, 2);
  add("joint_damping", c.joint, 0);
  add("joint_frictionloss", c.joint, 0);
  add("joint_armature", c.joint, 0);
  add("joint_stiffness", c.joint, 0);
  add("geom_friction", c.geom, 0);
  add("actuator_gain", c.actuator, 0);
  add("actuator_gear", c.actuator, 0);
  add("tendon_damping", c.tendon, 0);
  add("tendon_stiffness", c.tendon, 0);
  add("tendon_frictionloss", c.tendon, 0);
  add("geom_solref", c.geom, 0);
  add("geom_solimp", c.geom, 0);
  add("actuator_kp", c.servo, 0);
  add("actuator_kv", c.servo, 0);
  add("body_inertial", c.inertial_body, 2);  // d2
  add("tendon_lengthspring", c.tendon, 0);
  add("actuator_ki", c.pid, 0);
  add("pair_solref", c.pair, 0);
  add("pair_solimp", c.pair, 1);
  add("pair_friction", c.pair, 0);
  add("dcmotor_motorconst", c.dcmotor, 0);
  add("dcmotor_resistance", c.dcmotor, 0);
  add("dcmotor_inductance", c.dcmotor, 0);
  add("dcmotor_cogging", c.dcmotor, 0);
  add("dcmotor_lugre", c.dcmotor, 2);  // Coulomb friction
  add("actuator_delay", c.delayed_actuator, 0);
  add("sensor_delay", c.delayed_sensor, 0);
  return kinds;
}

const char* StageName(int stage) {
  if (stage == mjSTAGE_VEL) return "skip pos+vel";
  if (stage == mjSTAGE_POS) return "skip pos";
  return "full";
}

// one line of the table and of the CSV
struct Row {
  std::string model;
  int nv = 0;
  std::string kind;
  int stage = 0;
  std::string mode;
  std::string differences;
  int T = 0;
  double step_us = 0;
  double jacobian_ms = 0;
  double cost = 0;      // measured, in nominal steps per column (per time step)
  double estimate = 0;  // JacobianCostPerStep, same units
  std::string solver;   // "tolerance=X" or "fixed" (tolerance 0), of the Simulator's model copy
};

void PrintHeader() {
  std::printf("%-19s %-17s %-16s %-8s %8s %12s %12s %10s\n", "param_kind", "stage", "mode", "diff",
              "step_us", "jacobian_ms", "cost[steps]", "estimate");
}

void PrintRow(const Row& r) {
  char stage[32];
  std::snprintf(stage, sizeof(stage), "%d %s", r.stage, StageName(r.stage));
  std::printf("%-19s %-17s %-16s %-8s %8.2f %12.3f %12.2f %10.2f\n", r.kind.c_str(), stage,
              r.mode.c_str(), r.differences.c_str(), r.step_us, r.jacobian_ms, r.cost, r.estimate);
  std::fflush(stdout);
}

// small sine controls, a different frequency per actuator, within the control range
RowMatrix SineControls(const mjModel& m, int T, double amplitude) {
  const int nu = static_cast<int>(m.nu);
  RowMatrix u(T, nu);
  for (int k = 0; k < T; ++k) {
    const double t = k * m.opt.timestep;
    for (int i = 0; i < nu; ++i) {
      double a = amplitude;
      if (m.actuator_ctrllimited[i]) {
        a *= 0.5 * (m.actuator_ctrlrange[2 * i + 1] - m.actuator_ctrlrange[2 * i]);
      }
      u(k, i) = a * std::sin(2.0 * M_PI * (0.5 + 0.3 * i) * t);
    }
  }
  return u;
}

// mean constraint-solver iterations per step of a rollout of m (a Simulator's private copy)
double MeanSolverIterations(const mjModel& m, const RowMatrix& ctrl) {
  DataPtr d = MakeData(m);
  long iterations = 0;
  for (int k = 0; k < ctrl.rows(); ++k) {
    mju_copy(d->ctrl, ctrl.row(k).data(), static_cast<int>(m.nu));
    mj_step(&m, d.get());
    iterations += d->solver_niter[0];
  }
  return static_cast<double>(iterations) / static_cast<double>(ctrl.rows());
}

// nominal step time: Rollout time / T of a Simulator without parameters
double StepSeconds(const mjModel& m, const SequenceInput& seq, int repeats,
                   const SimulatorOptions& options) {
  Simulator sim(m, {}, options);
  const std::vector<SequenceInput> seqs = {seq};
  std::vector<Trajectory> out;
  const double t = TimeMedian(repeats, 1, [&] { sim.Rollout(seqs, &out); });
  return t / static_cast<double>(seq.ctrl.rows());
}

// the perturbed step of matrix mode for parameter 0 of a Simulator: after a full mj_forward at
// x_k with the nominal model, RestoreStep and StepSkip from the parameter's stage with the
// perturbed model. Once() times two loops over the trajectory, with and without the perturbed
// step, and returns the difference, so that no clock is read inside the loop.
class SkipStep {
 public:
  SkipStep(const Simulator& sim, const Trajectory& nom, const RowMatrix& ctrl)
      : m_(sim.model()), dims_(m_), nom_(nom), ctrl_(ctrl), plus_(CopyModel(m_)), d_(MakeData(m_)) {
    RestoreInputs(m_, dims_, nom_, d_.get());
    const double p = sim.GetParameters()[0];
    const double h = sim.ParameterSteps(JacobianOptions())[0];
    sim.parameters().WriteOne(plus_.get(), d_.get(), 0, p + h);
    stage_ = sim.parameters()[0].stage();
    Loop(true);  // warm up
  }

  double Once() {
    const double base = Loop(false);
    return Loop(true) - base;
  }

 private:
  double Loop(bool perturbed) {
    const double t0 = Now();
    for (int k = 0; k < nom_.T; ++k) {
      RestoreStep(m_, dims_, nom_, k, ctrl_.row(k).data(), d_.get());
      mj_forward(&m_, d_.get());
      if (perturbed) {
        RestoreStep(*plus_, dims_, nom_, k, ctrl_.row(k).data(), d_.get());
        StepSkip(plus_.get(), d_.get(), stage_, false);
      }
    }
    return SecondsSince(t0);
  }

  const mjModel& m_;
  const StateDims dims_;
  const Trajectory& nom_;
  const RowMatrix& ctrl_;
  ModelPtr plus_;
  DataPtr d_;
  int stage_ = mjSTAGE_NONE;
};

struct Settings {
  int repeats = 5;
  bool quick = false;
  double amplitude = 0.2;
  int steps = 0;                   // samples per rollout (0: the model's default)
  double pair_budget = 1.0;        // seconds of matrix-mode pairs per kind and side, at least
  std::vector<std::string> kinds;  // empty: all
  SimulatorOptions sim;            // threads = 1
};

// forward-difference numbers of one parameter kind, for the crossover summary
struct Summary {
  std::string kind;
  int stage;
  double directional, matrix, marginal, skip_step, matrix_est, marginal_est;
};

// the model's line, the nominal step time and the constraint solver; returns the solver's name
// for the rows
std::string PrintModel(const std::string& name, const mjModel* m, const SequenceInput& seq, int T,
                       const Settings& settings) {
  const int nv = static_cast<int>(m->nv);
  // baseline: one nominal step of a Simulator without parameters (each row below divides by the
  // nominal rollout of its own Simulator, timed next to the Jacobian)
  const int base_repeats = std::max(settings.repeats, 5);
  const double step_s = StepSeconds(*m, seq, base_repeats, settings.sim);
  std::printf("\n== %s: nq=%d nv=%d na=%d nu=%d nsensordata=%d timestep=%g, T=%d ==\n",
              name.c_str(), static_cast<int>(m->nq), nv, static_cast<int>(m->na),
              static_cast<int>(m->nu), static_cast<int>(m->nsensordata), m->opt.timestep, T);
  std::printf("nominal step: %.3f us (Simulator::Rollout / T, no parameters, median of %d)\n",
              step_s * 1e6, base_repeats);
  std::string solver = "fixed";
  {
    Simulator sim(*m, {}, settings.sim);
    const mjOption& o = sim.model().opt;
    if (o.tolerance > 0) {
      char buf[32];
      std::snprintf(buf, sizeof(buf), "tolerance=%g", o.tolerance);
      solver = buf;
    }
    std::printf("constraint solver: %s, at most %d iterations, %.2f iterations per nominal step\n",
                solver.c_str(), o.iterations, MeanSolverIterations(sim.model(), seq.ctrl));
  }
  return solver;
}

// the rows of one parameter kind (two objects of it): directional and whole-rollout columns, the
// matrix mode with one and two parameters, and matrix mode's perturbed step alone; its forward
// numbers into *summary (kinds of a model with native delays: whole rollouts only, no summary)
void BenchKind(const std::string& name, const mjModel* m, const KindCase& kc,
               const std::vector<SequenceInput>& seqs, int T, const std::string& solver,
               const Settings& settings, std::vector<Row>* rows_out,
               std::vector<Summary>* summary) {
  const int nv = static_cast<int>(m->nv);
  std::vector<Row>& rows = *rows_out;
  ParameterSpec spec1{kc.kind, kc.object[0], "", kc.index, ""};
  ParameterSpec spec2{kc.kind, kc.object[1], "", kc.index, ""};
  try {
    Simulator sim1(*m, {spec1}, settings.sim);
    Simulator sim2(*m, {spec1, spec2}, settings.sim);
    const int stage = sim1.parameters()[0].stage();
    std::vector<Trajectory> nom1, nom2;
    sim1.Rollout(seqs, &nom1);
    sim2.Rollout(seqs, &nom2);
    // estimates with the contact share of the nominal trajectory, as Jacobians() uses it
    const double contacts = ContactFraction(nom1);
    std::vector<Sensitivity> sens;
    std::vector<Trajectory> scratch;
    // the nominal rollout of sim1, timed before every timed Jacobian, so that each ratio
    // compares two times taken a moment apart (the machine's speed drifts)
    auto rollout = [&] {
      const double t0 = Now();
      sim1.Rollout(seqs, &scratch);
      return SecondsSince(t0);
    };
    auto timed = [&](const std::function<void()>& fn) {
      const double t0 = Now();
      fn();
      return SecondsSince(t0);
    };
    // one row from per-repeat rollout and Jacobian times: cost = median of their ratios
    Row row;
    row.model = name, row.nv = nv, row.kind = kc.kind, row.stage = stage, row.T = T;
    row.solver = solver;
    auto emit = [&](const std::string& mode, const std::string& diff,
                    const std::vector<double>& t_rollout, const std::vector<double>& t_jac,
                    double estimate) {
      std::vector<double> ratio;
      for (size_t r = 0; r < t_jac.size(); ++r) ratio.push_back(t_jac[r] / t_rollout[r]);
      row.mode = mode, row.differences = diff;
      row.step_us = Median(t_rollout) / T * 1e6;
      row.jacobian_ms = Median(t_jac) * 1e3;
      row.cost = Median(ratio);
      row.estimate = estimate;
      PrintRow(row);
      rows.push_back(row);
      return row.cost;
    };
    Summary sum{kc.kind, stage, 0, 0, 0, 0, 0, 0};
    const bool history = sim1.model().nhistory > 0;

    for (bool central : {false, true}) {
      const char* diff = central ? "central" : "forward";
      JacobianOptions opt;
      opt.central = central;
      // directional and whole rollout: one column, one warmup call (a model with history
      // buffers has whole-rollout Jacobians only: docs/numerics.md, native delays)
      for (JacobianMode mode : {JacobianMode::kDirectional, JacobianMode::kWholeRollout}) {
        if (history && mode != JacobianMode::kWholeRollout) continue;
        opt.mode = mode;
        auto jac = [&] { sim1.Jacobians(seqs, nom1, opt, &sens); };
        jac();
        std::vector<double> tr, tj;
        for (int r = 0; r < settings.repeats; ++r) {
          tr.push_back(rollout());
          tj.push_back(timed(jac));
        }
        const double cost = emit(JacobianModeName(mode), diff, tr, tj,
                                 sim1.JacobianCostPerStep(mode, opt, contacts));
        if (!central && mode == JacobianMode::kDirectional) sum.directional = cost;
      }
      if (history) continue;
      // matrix: 1 and 2 parameters, interleaved, and the median of the paired differences;
      // the difference is small next to the shared mjd_transitionFD, so more pairs while cheap
      opt.mode = JacobianMode::kMatrix;
      std::vector<double> tr, t1, dt;
      const double pairs_start = Now();
      for (int r = 0; r < settings.repeats || (r < 5 * settings.repeats &&
                                               SecondsSince(pairs_start) < settings.pair_budget);
           ++r) {
        tr.push_back(rollout());
        const double a = timed([&] { sim1.Jacobians(seqs, nom1, opt, &sens); });
        const double b = timed([&] { sim2.Jacobians(seqs, nom2, opt, &sens); });
        t1.push_back(a);
        dt.push_back(b - a);
      }
      const double est1 = sim1.JacobianCostPerStep(JacobianMode::kMatrix, opt, contacts);
      const double est2 = sim2.JacobianCostPerStep(JacobianMode::kMatrix, opt, contacts);
      const double matrix = emit("matrix", diff, tr, t1, est1);
      const double marginal = emit("matrix_marginal", diff, tr, dt, est2 - est1);
      if (!central) {
        sum.matrix = matrix, sum.marginal = marginal;
        sum.matrix_est = est1, sum.marginal_est = est2 - est1;
      }
    }
    if (history) return;  // no matrix mode: no crossover
    // the perturbed step of matrix mode alone (forward differences: one per parameter)
    SkipStep skip(sim1, nom1[0], seqs[0].ctrl);
    std::vector<double> tr, ts;
    for (int r = 0; r < settings.repeats; ++r) {
      tr.push_back(rollout());
      ts.push_back(skip.Once());
    }
    sum.skip_step = emit("skip_step", "forward", tr, ts, sum.marginal_est);
    summary->push_back(sum);
  } catch (const std::exception& e) {
    std::printf("%-19s failed: %s\n", kc.kind.c_str(), e.what());
  }
}

// what kAuto picks (counts only) for one body mass, alone and with the initial state, and the two
// modes' costs with the initial-state columns that check the choice
void CheckAutoChoice(const std::string& name, const mjModel* m, const ModelCase& mc,
                     const std::vector<SequenceInput>& seqs, int T, const std::string& solver,
                     const Settings& settings, std::vector<Row>* rows_out) {
  const int nv = static_cast<int>(m->nv);
  std::vector<Row>& rows = *rows_out;
  if (!mc.body[0].empty() && m->nhistory == 0) {
    Simulator sim(*m, {{"body_mass", mc.body[0], "", 0, ""}}, settings.sim);
    // kAuto as Simulator::Jacobians decides it: with the contact share of the trajectories
    std::vector<Trajectory> nom, scratch;
    std::vector<Sensitivity> sens;
    sim.Rollout(seqs, &nom);
    const double contacts = ContactFraction(nom);
    JacobianOptions opt;
    const char* one = JacobianModeName(sim.ChooseJacobianMode(opt, contacts));
    opt.initial_state = true;
    const int ncol = 1 + 2 * nv + static_cast<int>(m->na);
    std::printf(
        "kAuto (steps with contacts near: %.0f%%): 1 parameter -> %s; 1 parameter + initial "
        "state (%d columns) -> %s\n",
        100 * contacts, one, ncol, JacobianModeName(sim.ChooseJacobianMode(opt, contacts)));
    // check that choice: both modes with the initial-state columns (forward differences); the
    // rows give the cost per column, as above (parameter kind "body_mass+x0")
    Row row;
    row.model = name, row.nv = nv, row.kind = "body_mass+x0", row.T = T, row.solver = solver;
    row.differences = "forward";
    for (JacobianMode mode : {JacobianMode::kDirectional, JacobianMode::kMatrix}) {
      opt.mode = mode;
      std::vector<double> tr, tj, ratio;
      for (int r = 0; r < settings.repeats; ++r) {
        double t0 = Now();
        sim.Rollout(seqs, &scratch);
        tr.push_back(SecondsSince(t0));
        t0 = Now();
        sim.Jacobians(seqs, nom, opt, &sens);
        tj.push_back(SecondsSince(t0));
        ratio.push_back(tj.back() / tr.back() / ncol);
      }
      row.mode = JacobianModeName(mode);
      row.step_us = Median(tr) / T * 1e6;
      row.jacobian_ms = Median(tj) * 1e3;
      row.cost = Median(ratio);
      row.estimate = sim.JacobianCostPerStep(mode, opt, contacts) / ncol;
      rows.push_back(row);
      std::printf("  %-13s with initial state: %7.1f steps per time step (estimate %.1f)\n",
                  row.mode.c_str(), row.cost * ncol, row.estimate * ncol);
    }
  }
}

// where matrix mode starts to win (forward differences): directional costs d per column, matrix
// b + c per column with b its cost without parameter columns and c the skip step, so matrix wins
// for np > b / (d - c) parameters of one kind
void PrintCrossovers(const std::vector<Summary>& summary) {
  std::printf(
      "matrix vs directional, forward differences: b = matrix cost without parameter columns "
      "(matrix - skip_step), crossover = b / (directional - skip_step) parameters of the kind "
      "(est: the same from JacobianCostPerStep)\n");
  std::printf("%-19s %8s %8s %8s %8s %10s %8s\n", "param_kind", "b", "b_est", "dir", "skip",
              "crossover", "est");
  for (const Summary& s : summary) {
    const double b = s.matrix - s.skip_step, b_est = s.matrix_est - s.marginal_est;
    // a saving under 0.1 steps per column is within the noise: matrix mode never wins
    auto crossover = [](double base, double saving) {
      char buf[32];
      if (saving < 0.1) return std::string("never");
      std::snprintf(buf, sizeof(buf), "%.0f", base / saving);
      return std::string(buf);
    };
    std::printf("%-19s %8.1f %8.1f %8.2f %8.2f %10s %8s\n", s.kind.c_str(), b, b_est, s.directional,
                s.skip_step, crossover(b, s.directional - s.skip_step).c_str(),
                crossover(b_est, 1 - s.marginal_est).c_str());
  }
}

// all rows of one model
std::vector<Row> BenchModel(const std::string& name, const std::string& path,
                            const Settings& settings) {
  std::vector<Row> rows;
  ModelPtr m = LoadModel(path);
  const ModelCase mc = CaseFor(name, *m, settings.quick);
  const int T = settings.steps > 0 ? settings.steps : mc.T;
  SequenceInput seq;
  seq.ctrl = SineControls(*m, T, settings.amplitude);
  const std::vector<SequenceInput> seqs = {seq};  // from the model's reference state
  const std::string solver = PrintModel(name, m.get(), seq, T, settings);
  PrintHeader();
  std::vector<Summary> summary;
  for (const KindCase& kc : KindsFor(mc)) {
    if (!settings.kinds.empty() &&
        std::find(settings.kinds.begin(), settings.kinds.end(), kc.kind) == settings.kinds.end()) {
      continue;
    }
    BenchKind(name, m.get(), kc, seqs, T, solver, settings, &rows, &summary);
  }
  CheckAutoChoice(name, m.get(), mc, seqs, T, solver, settings, &rows);
  PrintCrossovers(summary);
  return rows;
}

void WriteCsv(const std::string& path, const std::vector<Row>& rows) {
  std::ofstream out(path);
  if (!out) throw std::runtime_error("cannot write " + path);
  out << "model,nv,param_kind,stage,mode,differences,T,step_us,jacobian_ms,cost_per_column_steps,"
         "estimate_steps,solver\n";
  char buf[256];
  for (const Row& r : rows) {
    std::snprintf(buf, sizeof(buf), "%s,%d,%s,%d,%s,%s,%d,%.4f,%.4f,%.4f,%.4f,%s\n",
                  r.model.c_str(), r.nv, r.kind.c_str(), r.stage, r.mode.c_str(),
                  r.differences.c_str(), r.T, r.step_us, r.jacobian_ms, r.cost, r.estimate,
                  r.solver.c_str());
    out << buf;
  }
}

int Main(int argc, char** argv) {
  InstallMujocoHandlers();
  CLI::App app{"bench_jacobian_cost: cost of one Jacobian column in units of one mj_step"};
  Settings settings;
  std::string models = "arm5,humanoid";
  std::string models_dir = MJSYSID_MODELS_DIR;
  std::string csv, kinds;
  bool fixed_iterations = false;
  std::string clock = "wall";
  app.add_flag("--quick", settings.quick, "fewer repeats, shorter rollouts");
  app.add_option("--models", models, "comma-separated model names (files MODELS_DIR/NAME.xml)");
  app.add_option("--models-dir", models_dir, "folder of the models");
  app.add_option("--csv", csv, "also write the table to this CSV file");
  app.add_option("--repeats", settings.repeats, "timed repeats per measurement (median)")
      ->check(CLI::PositiveNumber);
  app.add_option("--steps", settings.steps,
                 "samples T per rollout (default: 1000 arm5, 200 humanoid)")
      ->check(CLI::PositiveNumber);
  app.add_option("--kinds", kinds, "comma-separated parameter kinds (default: all that apply)");
  app.add_flag("--fixed-solver-iterations", fixed_iterations,
               "SimulatorOptions::fixed_solver_iterations (opt.tolerance = 0, so the constraint "
               "solver runs opt.iterations every step); default: SimulatorOptions' tolerance");
  app.add_option("--clock", clock, "wall (steady_clock) or cpu (process CPU time)")
      ->check(CLI::IsMember({"wall", "cpu"}));
  CLI11_PARSE(app, argc, argv);
  cpu_clock = clock == "cpu";
  if (settings.quick && app.count("--repeats") == 0) settings.repeats = 3;
  if (settings.quick) settings.pair_budget = 0.2;
  settings.kinds = Split(kinds, ',');
  settings.sim.threads = 1;
  settings.sim.fixed_solver_iterations = fixed_iterations;

  std::printf(
      "bench_jacobian_cost: mjsysid %s, MuJoCo %s, 1 thread, %s clock, median of %d, solver "
      "iterations %s\n",
      MJSYSID_VERSION, MujocoVersion().c_str(), clock.c_str(), settings.repeats,
      fixed_iterations ? "fixed (tolerance 0)" : "to tolerance");
  std::printf(
      "cost = Jacobian time / (T * nominal step time), the step timed next to it: steps per "
      "column per time step; estimate = Simulator::JacobianCostPerStep.\n"
      "matrix_marginal = matrix mode with 2 parameters of the kind minus with 1 (median of "
      "paired "
      "differences); skip_step = matrix mode's perturbed step for the parameter alone "
      "(mj_setState + StepSkip from its stage).\n");
  const auto start = std::chrono::steady_clock::now();
  std::printf("load average at start: %.2f\n", LoadAverage());
  std::vector<Row> rows;
  for (const std::string& name : Split(models, ',')) {
    std::vector<Row> r = BenchModel(name, models_dir + "/" + name + ".xml", settings);
    rows.insert(rows.end(), r.begin(), r.end());
  }
  std::printf("\ntotal %.1f s wall, load average at end: %.2f\n",
              std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count(),
              LoadAverage());
  if (!csv.empty()) {
    WriteCsv(csv, rows);
    std::printf("wrote %s\n", csv.c_str());
  }
  return 0;
}

}  // namespace
}  // namespace mjsysid

int main(int argc, char** argv) {
  try {
    return mjsysid::Main(argc, argv);
  } catch (const std::exception& e) {
    std::fprintf(stderr, "bench_jacobian_cost: %s\n", e.what());
    return 1;
  }
}
