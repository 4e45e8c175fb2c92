// bench_fit: run time against parameter error of whole fits, per experiment and method, side by
// side with the peers (issue 6).
//
// For every case (an experiment file with a `simulate:` block: its log is simulated when missing)
// and every method it fits the same data from the same start within the same bounds, and records
// wall time, LM iterations, simulation step calls, initial and final cost and the parameter
// error against the truth of `simulate.truth`:
// - ours/<mode>/<differences>/<threads>t: Problem::Fit with the core Jacobians, mode directional
//   or matrix, forward or central differences, 1 or 2 simulator threads;
// - ours/directional/forward+auto/<threads>t: ours from the equation-error start (every
//   parameter `initial: auto`, sysid/equation_error.h), 1 and 2 threads, method `auto`;
// - oracle/whole/forward/2t: Problem::Fit with whole-rollout finite differences (kWholeRollout);
// - full-model/directional/forward/<threads>t: ours without the reduced model
//   (solver.reduce_model: false, core/reduced_model.h), method `full` (issue 15 item 6):
//   the same estimate bit for bit, so only the time differs from ours/directional/forward;
// - ceres-numdiff/forward/1t: what a C++ user writes by hand: ceres::DynamicNumericDiffCostFunction
//   around a plain mj_step loop over every sequence (one residual block, Ceres' default relative
//   step), same residual, bounds, log transforms and solver settings as ours;
// - mujoco.sysid/<threads>t: rows read from the peer driver's peer_result.json files
//   (tools/peer/mujoco_sysid_fit.py, run by tools/bench/run_fit_benchmarks.sh) in
//   --peer-dir/<case>-<threads>t/ (parameters with `transform: log` optimised as log p, like ours)
//   and mujoco.sysid/physical from <case>-phys-2t/ (physical units, the peer's own way).
// Also, per case, the nominal step time t_step (1-thread rollouts of every sequence with the model
// file's parameter values) and, per row, the ratio of the time per iteration to the floor
// (1 + np) * sum(T) * t_step / threads; for ours directional forward also the path floor: the
// step time at each iterate of the row's fit (the point whose Jacobian and trial the iteration
// simulates, FitResult::trace) relative to the nominal one (RelativeStepTimeAt), averaged over
// the iterations and times t_step, since a contact-rich model's step cost depends on its
// parameters (box_floor: 1.5x between the start and the estimate).
//
// Output: a table on stdout, DIR/fit_bench.csv, DIR/fit_bench.json (rows, machine, versions,
// command), DIR/fit_bench.md (the table in Markdown) and DIR/error_vs_time.svg (one panel per
// case). Timings are wall clock; nothing here
// is asserted.
#include <ceres/ceres.h>
#include <mujoco/mujoco.h>

#include <CLI/CLI.hpp>
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <ctime>
#include <filesystem>
#include <fstream>
#include <functional>
#include <map>
#include <nlohmann/json.hpp>
#include <sstream>
#include <string>
#include <thread>
#include <tuple>
#include <vector>

#include "core/mujoco_env.h"
#include "core/parameters.h"
#include "core/simulator.h"
#include "core/state.h"
#include "mjsysid/version.h"
#include "sysid/fit_ledger.h"
#include "sysid/io/atomic_file.h"
#include "sysid/io/experiment.h"
#include "sysid/io/log.h"
#include "sysid/problem.h"
#include "sysid/run/fit_experiment.h"
#include "sysid/sim/simulate.h"

namespace mjsysid {
namespace {

namespace fs = std::filesystem;
using Clock = std::chrono::steady_clock;

double Seconds(Clock::time_point t0) {
  return std::chrono::duration<double>(Clock::now() - t0).count();
}

// one row of the table
struct Row {
  std::string case_name, method, status, note;
  int threads = 1, np = 0, sequences = 0;
  long long samples = 0;  // sum of T over the sequences
  double wall_s = NAN;
  int iterations = 0;
  long long steps = 0;  // simulation step calls (Simulator::StepCount; own count for the others)
  double initial_cost = NAN, final_cost = NAN;
  double max_rel_error = NAN, rms_rel_error = NAN;
  double t_step_us = NAN;    // nominal step time of the case
  double floor_ratio = NAN;  // (wall / iteration) / ((1 + np) * samples * t_step / threads)
  // ours: the point each iteration of the fit simulates (b.parameters' order), and t_step
  // averaged over them with the floor ratio it gives (the path floor)
  std::vector<Eigen::VectorXd> path;
  double path_t_step_us = NAN, path_floor_ratio = NAN;
  std::vector<std::pair<std::string, double>> estimates;
  // the load just before the row (MachineLoad): cores kept busy by other processes over one
  // second, the 1-minute load average, and whether the row ran idle (others <= 0.5 core per
  // thread of the row)
  double others_cores = NAN, load1 = NAN;
  bool idle = true;
  // the host's speed around the row (HostSlowness before and after it, the larger): 1 = as fast
  // as ever measured for the case; attempts: how often the row was measured (kMaxAttempts)
  double host_slowness = NAN;
  int attempts = 1;
  // ours: the fit's ledger (sysid/fit_ledger.h) and the seconds of run::BuildProblem before it
  // (model loading, log reading, not part of wall_s)
  std::vector<LedgerRow> ledger;
  double build_s = NAN;
  // CPU seconds of the whole process (all threads) during the fit: less sensitive than wall time
  // to other processes on the machine (printed with --ledger)
  double cpu_s = NAN;
  // runs of the fit behind the row: wall_s is the fastest (--repeats; the estimates, iterations
  // and steps of every run are the same)
  int runs = 1;
};

// the process's CPU time (all threads), seconds
double ProcessCpuSeconds() { return static_cast<double>(std::clock()) / CLOCKS_PER_SEC; }

// the case: experiment, truth, data
struct Case {
  std::string name;
  io::ExperimentConfig config;
  std::map<std::string, double> truth;
  double t_step = 0;  // seconds per nominal step (1 thread)
  // the problem as built for the step times, and the step time at each point measured so far,
  // relative to the nominal step's measured next to it (so that the host's speed cancels)
  std::shared_ptr<run::BuiltProblem> built;
  std::map<std::vector<double>, double> relative_t_step_at;
  long long samples = 0;
  int sequences = 0;
};

void Errors(const Case& c, Row* row) {
  double worst = 0, sum = 0;
  int n = 0;
  for (const auto& [name, value] : row->estimates) {
    const auto it = c.truth.find(name);
    if (it == c.truth.end() || it->second == 0) continue;
    const double e = std::abs(value / it->second - 1.0);
    worst = std::max(worst, std::isfinite(e) ? e : INFINITY);
    sum += e * e;
    ++n;
  }
  row->max_rel_error = n ? worst : NAN;
  row->rms_rel_error = n ? std::sqrt(sum / n) : NAN;
}

double RelativeStepTimeAt(Case* c, const Eigen::VectorXd& values);

// the row's floor ratios with the case's t_step as it stands (the fastest measured so far)
void Floor(Case* c, Row* row) {
  row->t_step_us = c->t_step * 1e6;
  if (!(row->iterations > 0) || !std::isfinite(row->wall_s)) return;
  const double per_t_step = (1.0 + row->np) * static_cast<double>(c->samples) / row->threads;
  row->floor_ratio = row->wall_s / row->iterations / (per_t_step * c->t_step);
  if (row->path.empty()) return;
  double sum = 0;
  for (const Eigen::VectorXd& p : row->path) sum += RelativeStepTimeAt(c, p);
  const double t_step = c->t_step * sum / static_cast<double>(row->path.size());
  row->path_t_step_us = t_step * 1e6;
  row->path_floor_ratio = row->wall_s / row->iterations / (per_t_step * t_step);
}

// loads the case and simulates its log when it is missing
Case LoadCase(const std::string& experiments_dir, const std::string& name) {
  Case c;
  c.name = name;
  c.config = io::LoadExperiment(experiments_dir + "/" + name + ".yaml");
  for (const io::NamedValue& t : c.config.simulate.truth) c.truth[t.name] = t.value;
  for (const io::DataFile& d : c.config.data) {
    if (!fs::exists(d.path)) {
      std::fprintf(stderr, "bench_fit: simulating %s -> %s\n", name.c_str(), d.path.c_str());
      fs::create_directories(fs::path(d.path).parent_path());
      io::WriteLog(d.path, sim::SimulateExperiment(c.config));
    }
  }
  return c;
}

// seconds per step of 1-thread rollouts (mj_step's calls, the sensor stage included) of every
// sequence on the full model, with the fitted parameters at values (b.parameters' order) or,
// values nullptr, at the model file's values: the fastest of passes over every sequence, repeated
// for at least min_seconds and min_reps passes
double StepTime(const run::BuiltProblem& b, const Eigen::VectorXd* values, double min_seconds,
                int min_reps) {
  double best = INFINITY;
  for (size_t mi = 0; mi < b.models.size(); ++mi) {
    std::vector<ParameterSpec> specs;
    std::vector<double> at;
    for (size_t i = 0; values && i < b.parameters.size(); ++i) {
      if (!b.parameters[i].AppliesTo(b.model_names[mi])) continue;
      specs.push_back(b.parameters[i].target);
      at.push_back((*values)[static_cast<Eigen::Index>(i)]);
    }
    SimulatorOptions so;
    so.threads = 1;
    // the floor is mj_step's work: MuJoCo's sensor stage runs even where a fit copies encoders
    so.copy_state_sensors = false;
    Simulator sim(*b.models[mi], specs, so);
    if (!at.empty()) sim.SetParameters(Eigen::Map<const Eigen::VectorXd>(at.data(), at.size()));
    std::vector<SequenceInput> ins;
    for (const FitSequence& s : b.sequences) {
      if (s.model == b.model_names[mi]) ins.push_back({s.x0, s.ctrl});
    }
    if (ins.empty()) continue;
    std::vector<Trajectory> trs;
    sim.Rollout(ins, &trs);  // warm up
    const auto t0 = Clock::now();
    int reps = 0;
    do {
      sim.ResetStepCount();
      const auto t1 = Clock::now();
      sim.Rollout(ins, &trs);
      best = std::min(best, Seconds(t1) / static_cast<double>(sim.StepCount()));
      ++reps;
    } while (Seconds(t0) < min_seconds || reps < min_reps);
  }
  return best;
}

// the case's nominal step time (the model file's values, >= 0.3 s and 3 passes)
void MeasureStep(Case* c) {
  c->built = std::make_shared<run::BuiltProblem>(run::BuildProblem(c->config, 1));
  c->sequences = static_cast<int>(c->built->sequences.size());
  c->samples = 0;
  for (const FitSequence& s : c->built->sequences) c->samples += s.ctrl.rows();
  c->t_step = StepTime(*c->built, nullptr, 0.3, 3);
}

// The host's speed now: the case's nominal step time (fastest of 3 passes, >= 0.05 s) over the
// fastest measured for the case, which it lowers when faster. This virtual machine's speed changes
// from outside (by up to 2x for minutes, BENCHMARKS.md "The machine on 2026-11-23"), which the
// load check cannot see: the probe can.
double HostSlowness(Case* c) {
  const double now = StepTime(*c->built, nullptr, 0.05, 3);
  c->t_step = std::min(c->t_step, now);
  return now / c->t_step;
}

// the step time at the fitted parameters' values over the nominal step time: the fastest of each
// over three alternating rounds (nominal, at the values, ..., nominal; >= 0.04 s and 2 passes
// each), so that a slow spell of the host has to cover every round of one to move the ratio;
// measured once per point
double RelativeStepTimeAt(Case* c, const Eigen::VectorXd& values) {
  const std::vector<double> key(values.data(), values.data() + values.size());
  const auto it = c->relative_t_step_at.find(key);
  if (it != c->relative_t_step_at.end()) return it->second;
  double nominal = StepTime(*c->built, nullptr, 0.04, 2), at = INFINITY;
  for (int round = 0; round < 3; ++round) {
    at = std::min(at, StepTime(*c->built, &values, 0.04, 2));
    nominal = std::min(nominal, StepTime(*c->built, nullptr, 0.04, 2));
  }
  c->t_step = std::min(c->t_step, nominal);
  return c->relative_t_step_at[key] = at / nominal;
}

// ours and the whole-rollout oracle: the product's own fit with one Jacobian setting
// auto_start: every parameter `initial: auto` (the equation-error start, sysid/equation_error.h)
// reduce: the reduced model (FitOptions::reduce_model)
Row FitOurs(const Case& c, const std::string& method, JacobianMode mode, bool central, int threads,
            int max_iterations, bool auto_start = false, bool reduce = true) {
  Row row;
  row.method = method;
  row.threads = threads;
  io::ExperimentConfig config = c.config;
  for (io::ParameterSpec& p : config.parameters) p.initial_auto = p.initial_auto || auto_start;
  const auto built = Clock::now();
  run::BuiltProblem b = run::BuildProblem(config, threads);
  row.build_s = Seconds(built);
  FitOptions o = b.options;
  o.jacobian.mode = mode;
  o.jacobian.central = central;
  o.threads = threads;
  o.verbose = false;
  o.on_iteration = nullptr;
  o.reduce_model = reduce;
  if (max_iterations > 0) o.max_iterations = max_iterations;
  row.np = static_cast<int>(b.parameters.size());
  try {
    const double cpu0 = ProcessCpuSeconds();
    const FitResult r = b.problem->Fit(o);
    row.cpu_s = ProcessCpuSeconds() - cpu0;
    row.wall_s = r.seconds;
    row.iterations = r.iterations;
    row.steps = r.simulation_steps;
    row.ledger = r.ledger;
    row.initial_cost = r.initial_cost;
    row.final_cost = r.final_cost;
    // the status a user of `sysid fit` sees (docs/cli.md), not only the optimizer's flag
    row.status = FitStatusName(r.outcome);
    for (const std::string& w : r.warnings) {
      if (w.rfind("initial: auto", 0) == 0) row.note += (row.note.empty() ? "" : "; ") + w;
    }
    for (size_t i = 0; i < b.parameters.size(); ++i) {
      row.estimates.emplace_back(r.parameters[i].name, r.parameters[i].value);
    }
    // iteration k (1-based) simulates its Jacobian and trial at the point after iteration k - 1;
    // the path floor for the directional forward rows (issue 15's), whose points each cost
    // seven short nominal and path passes (RelativeStepTimeAt)
    const bool path = mode == JacobianMode::kDirectional && !central;
    for (int k = 0; path && k < r.iterations && k < static_cast<int>(r.trace.size()); ++k) {
      row.path.push_back(r.trace[k].parameters.head(row.np));
    }
  } catch (const std::exception& e) {
    row.status = "failed";
    row.note = e.what();
  }
  return row;
}

// ---------------------------------------------------------------------------------------------
// the hand-written baseline: Ceres numeric differentiation of whole rollouts

class WholeRolloutResidual {
 public:
  WholeRolloutResidual(const run::BuiltProblem& b, const FitOptions& o)
      : b_(b), model_(CopyModel(*b.models[0])), data_(MakeData(*model_)) {
    // the same solver tolerance as the product's simulator (core/simulator.h)
    model_->opt.tolerance = std::min(model_->opt.tolerance, 1e-10);
    std::vector<ParameterSpec> specs;
    for (const FitParameter& p : b.parameters) specs.push_back(p.target);
    params_ = ParameterSet(*model_, specs);
    params_.Prepare(model_.get());
    for (const FitSequence& s : b.sequences) {
      std::vector<std::pair<int, double>> ch;
      std::vector<std::string> names = s.sensors;
      if (names.empty()) {
        for (int i = 0; i < model_->nsensor; ++i)
          names.push_back(mj_id2name(model_.get(), mjOBJ_SENSOR, i));
      }
      for (const std::string& n : names) {
        const int id = mj_name2id(model_.get(), mjOBJ_SENSOR, n.c_str());
        const auto it = o.sensor_weights.find(n);
        const double w = it == o.sensor_weights.end() ? 1.0 : it->second;
        for (int k = 0; k < model_->sensor_dim[id]; ++k)
          ch.emplace_back(model_->sensor_adr[id] + k, w);
      }
      residuals_ += static_cast<int>(s.ctrl.rows() * ch.size());
      channels_.push_back(ch);
    }
  }
  int num_residuals() const { return residuals_; }
  long long steps() const { return steps_; }

  bool operator()(double const* const* z, double* r) const {
    std::vector<double> p(params_.size());
    for (int j = 0; j < params_.size(); ++j) p[j] = b_.parameters[j].FromVariable(z[0][j]);
    mjModel* m = model_.get();
    mjData* d = data_.get();
    params_.Write(m, d, p.data());
    int row = 0;
    for (size_t q = 0; q < b_.sequences.size(); ++q) {
      const FitSequence& s = b_.sequences[q];
      mj_resetData(m, d);
      mju_copy(d->qpos, s.x0.qpos.data(), m->nq);
      mju_copy(d->qvel, s.x0.qvel.data(), m->nv);
      if (m->na) mju_copy(d->act, s.x0.act.data(), m->na);
      d->time = s.x0.time;
      for (int k = 0; k < s.ctrl.rows(); ++k) {
        mju_copy(d->ctrl, s.ctrl.row(k).data(), m->nu);
        mj_step(m, d);  // sensors of x_k (mj_step evaluates them before integrating)
        ++steps_;
        for (const auto& [col, w] : channels_[q]) {
          r[row++] = w * (d->sensordata[col] - s.measured(k, col));
        }
      }
      for (int i = 0; i < mjNWARNING; ++i) {
        if (d->warning[i].number > 0) return false;  // a divergent trial point: rejected
      }
    }
    for (int i = 0; i < row; ++i) {
      if (!std::isfinite(r[i])) return false;
    }
    return true;
  }

 private:
  const run::BuiltProblem& b_;
  ModelPtr model_;
  DataPtr data_;
  ParameterSet params_;
  std::vector<std::vector<std::pair<int, double>>> channels_;
  int residuals_ = 0;
  mutable long long steps_ = 0;
};

// what the numeric-diff baseline cannot express (it is one model, one shooting segment)
std::string NumDiffUnsupported(const run::BuiltProblem& b) {
  if (b.models.size() != 1) return "several models";
  if (b.options.segment_steps > 0) return "multiple shooting";
  if (b.options.estimate_initial_state) return "initial-state estimation";
  if (!b.measurements.empty()) return "measurement terms";
  if (b.options.loss != LossType::kNone) return "per-residual robust loss";
  for (const FitParameter& p : b.parameters) {
    if (p.has_prior) return "priors";
  }
  return "";
}

Row FitNumDiff(const Case& c, int max_iterations) {
  Row row;
  row.method = "ceres-numdiff/forward";
  row.threads = 1;
  run::BuiltProblem b = run::BuildProblem(c.config, 1);
  row.np = static_cast<int>(b.parameters.size());
  const std::string why = NumDiffUnsupported(b);
  if (!why.empty()) {
    row.status = "n/a";
    row.note = why;
    return row;
  }
  const auto t0 = Clock::now();
  const double cpu0 = ProcessCpuSeconds();
  auto* functor = new WholeRolloutResidual(b, b.options);
  auto* cost = new ceres::DynamicNumericDiffCostFunction<WholeRolloutResidual, ceres::FORWARD>(
      functor, ceres::TAKE_OWNERSHIP);
  const int np = row.np;
  cost->AddParameterBlock(np);
  cost->SetNumResiduals(functor->num_residuals());
  std::vector<double> z(np);
  for (int j = 0; j < np; ++j) z[j] = b.parameters[j].ToVariable(b.parameters[j].initial);
  ceres::Problem problem;
  problem.AddResidualBlock(cost, nullptr, z.data());
  for (int j = 0; j < np; ++j) {
    const FitParameter& p = b.parameters[j];
    const double lo = p.ToVariable(p.lower), hi = p.ToVariable(p.upper);
    if (std::isfinite(lo)) problem.SetParameterLowerBound(z.data(), j, std::min(lo, hi));
    if (std::isfinite(hi)) problem.SetParameterUpperBound(z.data(), j, std::max(lo, hi));
  }
  ceres::Solver::Options so;
  so.trust_region_strategy_type = ceres::LEVENBERG_MARQUARDT;
  so.linear_solver_type = ceres::DENSE_QR;
  so.max_num_iterations = max_iterations > 0 ? max_iterations : b.options.max_iterations;
  so.function_tolerance = b.options.function_tolerance;
  so.gradient_tolerance = b.options.gradient_tolerance;
  so.parameter_tolerance = b.options.parameter_tolerance;
  so.logging_type = ceres::SILENT;
  // no projected line search along bounded steps (its gradient evaluations: one Jacobian per
  // trial length); sysid/problem.cc keeps it with quadratic interpolation (cost values only)
  so.max_num_line_search_step_size_iterations = 0;
  ceres::Solver::Summary summary;
  ceres::Solve(so, &problem, &summary);
  row.wall_s = Seconds(t0);
  row.cpu_s = ProcessCpuSeconds() - cpu0;
  row.iterations = static_cast<int>(summary.iterations.size()) - 1;
  row.steps = functor->steps();
  row.initial_cost = summary.initial_cost;
  row.final_cost = summary.final_cost;
  row.status = summary.termination_type == ceres::CONVERGENCE ? "converged"
               : summary.termination_type == ceres::FAILURE   ? "failed"
                                                              : "stopped";
  for (int j = 0; j < np; ++j) {
    row.estimates.emplace_back(b.parameters[j].name, b.parameters[j].FromVariable(z[j]));
  }
  return row;
}

// ---------------------------------------------------------------------------------------------
// the peer's rows, from the driver's JSON

// j[key] into *out when it is a number
bool JsonNumber(const nlohmann::json& j, const char* key, double* out) {
  const auto it = j.find(key);
  if (it == j.end() || !it->is_number()) return false;
  *out = it->get<double>();
  return true;
}

Row PeerRow(const Case& c, const std::string& dir, int threads, const std::string& method) {
  Row row;
  row.method = method;
  row.threads = threads;
  const std::string path = dir + "/peer_result.json";
  const std::string skip = dir + "/unsupported.txt";
  if (!fs::exists(path)) {
    row.status = "n/a";
    std::ifstream in(skip);
    std::string line;
    if (in && std::getline(in, line))
      row.note = line;
    else
      row.note = "no peer result (run tools/bench/run_fit_benchmarks.sh)";
    return row;
  }
  nlohmann::json t;
  try {
    std::ifstream in(path);
    t = nlohmann::json::parse(in);
  } catch (const nlohmann::json::exception& e) {
    row.status = "n/a";
    row.note = path + " is not valid JSON: " + e.what();
    return row;
  }
  double v = 0;
  if (JsonNumber(t, "wall_time_s", &v)) row.wall_s = v;
  if (JsonNumber(t, "runs", &v)) row.runs = static_cast<int>(v);
  if (JsonNumber(t, "iterations", &v)) row.iterations = static_cast<int>(v);
  if (JsonNumber(t, "initial_cost", &v)) row.initial_cost = v;
  if (JsonNumber(t, "final_cost", &v)) row.final_cost = v;
  if (JsonNumber(t, "rollout_columns", &v)) row.steps = static_cast<long long>(v) * c.samples;
  // estimates: parameters.<name>.estimate
  const auto params = t.find("parameters");
  for (const io::ParameterSpec& p : c.config.parameters) {
    if (params == t.end() || !params->is_object() || !params->contains(p.name)) continue;
    if (JsonNumber(params->at(p.name), "estimate", &v)) row.estimates.emplace_back(p.name, v);
  }
  // the load before the peer's run, as run_fit_benchmarks.sh measured it: "<others> <load1> <idle>"
  std::ifstream load(dir + "/load.txt");
  int idle = 1;
  if (load >> row.others_cores >> row.load1 >> idle) row.idle = idle != 0;
  row.np = static_cast<int>(c.config.parameters.size());
  row.status = "done";
  row.note = "stops on its own tolerances";
  return row;
}

// ---------------------------------------------------------------------------------------------
// output

std::string Num(double v, const char* fmt = "%.6g") {
  if (std::isnan(v)) return "";
  char buf[64];
  std::snprintf(buf, sizeof(buf), fmt, v);
  return buf;
}

// ---------------------------------------------------------------------------------------------
// the load before each row

// the jiffies of all cpus: {busy, total} from the first line of /proc/stat
std::pair<double, double> CpuJiffies() {
  std::ifstream in("/proc/stat");
  std::string cpu;
  in >> cpu;
  double v[8] = {0, 0, 0, 0, 0, 0, 0, 0}, total = 0;
  for (double& x : v) {
    in >> x;
    total += x;
  }
  return {total - v[3] - v[4], total};  // idle and iowait are not busy
}

// the cores other processes kept busy over `seconds` (this program sleeps meanwhile) and the
// 1-minute load average (/proc/loadavg; it also counts this program's previous row for a minute,
// which is why the decision uses the first number)
std::pair<double, double> MachineLoad(double seconds) {
  const auto [busy0, total0] = CpuJiffies();
  std::this_thread::sleep_for(std::chrono::duration<double>(seconds));
  const auto [busy1, total1] = CpuJiffies();
  const double cores = std::thread::hardware_concurrency();
  const double others = total1 > total0 ? cores * (busy1 - busy0) / (total1 - total0) : NAN;
  double load1 = NAN;
  std::ifstream("/proc/loadavg") >> load1;
  return {others, load1};
}

// the host counts as steady around a row when its probe (HostSlowness) stays within 8 % of the
// fastest; a row that was not is measured again after kHostWait seconds, up to kMaxAttempts in all
constexpr double kSteadyHost = 1.08;
constexpr int kMaxAttempts = 3;
constexpr double kHostWait = 10;

// before a row of `threads` threads: waits up to wait_s seconds for the machine to be idle for it
// (other processes using <= 0.5 core per thread of the row) and records the load in the row;
// not idle after the wait: the row says so in its note and runs anyway
void WaitForIdle(int threads, double wait_s, Row* row) {
  const auto t0 = Clock::now();
  do {
    std::tie(row->others_cores, row->load1) = MachineLoad(1.0);
    row->idle = row->others_cores <= 0.5 * threads;
  } while (!row->idle && Seconds(t0) < wait_s);
}

// the row's load note ("" when idle)
std::string LoadNote(const Row& r) {
  if (r.idle) return "";
  return "not idle: others used " + Num(r.others_cores, "%.2f") + " cores, load average " +
         Num(r.load1, "%.2f");
}

void PrintRow(const Row& r) {
  std::printf("%-16s %-28s %2d %-10s %9s %5d %12lld %11s %11s %10s %8s %8s  %s\n",
              r.case_name.c_str(), r.method.c_str(), r.threads, r.status.c_str(),
              Num(r.wall_s, "%.3f").c_str(), r.iterations, r.steps,
              Num(r.final_cost, "%.6g").c_str(), Num(r.max_rel_error, "%.2e").c_str(),
              Num(r.rms_rel_error, "%.2e").c_str(), Num(r.floor_ratio, "%.2f").c_str(),
              Num(r.path_floor_ratio, "%.2f").c_str(), r.note.c_str());
  std::fflush(stdout);
}

// Per case and thread count: our fastest row against the fastest peer row (Ceres numeric diff,
// mujoco.sysid in either parametrization) at the same number of threads, and our iterations
// against the peer's fewest (any row). speedup = peer wall / our wall (> 1: ours is faster).
struct Ratio {
  std::string case_name;
  int threads = 1;
  const Row* ours = nullptr;
  const Row* peer = nullptr;
  int peer_fewest_iterations = 0;  // 0: no peer row finished
  double speedup = NAN;
};

bool Finished(const Row& r) { return std::isfinite(r.wall_s) && r.iterations > 0; }
bool IsOurs(const Row& r) { return r.method.rfind("ours/", 0) == 0; }
bool IsPeer(const Row& r) {
  return r.method.rfind("ceres-numdiff", 0) == 0 || r.method.rfind("mujoco.sysid", 0) == 0;
}

std::vector<Ratio> Ratios(const std::vector<std::string>& cases, const std::vector<Row>& rows) {
  std::vector<Ratio> out;
  for (const std::string& name : cases) {
    int fewest = 0;
    for (const Row& r : rows) {
      if (r.case_name == name && IsPeer(r) && Finished(r)) {
        fewest = fewest ? std::min(fewest, r.iterations) : r.iterations;
      }
    }
    for (int threads : {1, 2}) {
      Ratio q;
      q.case_name = name;
      q.threads = threads;
      q.peer_fewest_iterations = fewest;
      for (const Row& r : rows) {
        if (r.case_name != name || r.threads != threads || !Finished(r)) continue;
        if (IsOurs(r) && (!q.ours || r.wall_s < q.ours->wall_s)) q.ours = &r;
        if (IsPeer(r) && (!q.peer || r.wall_s < q.peer->wall_s)) q.peer = &r;
      }
      if (q.ours && q.peer) q.speedup = q.peer->wall_s / q.ours->wall_s;
      if (q.ours) out.push_back(q);
    }
  }
  return out;
}

std::string RatioLine(const Ratio& q, const char* sep) {
  std::ostringstream f;
  f << q.case_name << sep << q.threads << sep << q.ours->method << sep
    << Num(q.ours->wall_s, "%.3f") << sep << q.ours->iterations << sep
    << (q.peer ? q.peer->method : std::string("n/a")) << sep
    << (q.peer ? Num(q.peer->wall_s, "%.3f") : "") << sep << Num(q.speedup, "%.2f") << sep
    << (q.peer_fewest_iterations ? std::to_string(q.peer_fewest_iterations) : "") << sep
    << (q.ours->idle && (!q.peer || q.peer->idle) ? "" : "not idle");
  return f.str();
}

void WriteCsv(const std::string& path, const std::vector<Row>& rows) {
  std::ostringstream f;
  f << "case,method,threads,status,wall_s,iterations,sim_steps,np,sequences,samples,t_step_us,"
       "floor_ratio,initial_cost,final_cost,max_rel_error,rms_rel_error,note,others_cores,load1,"
       "idle,path_t_step_us,path_floor_ratio,host_slowness,attempts\n";
  for (const Row& r : rows) {
    std::string note = r.note;
    std::replace(note.begin(), note.end(), ',', ';');
    std::replace(note.begin(), note.end(), '\n', ' ');
    f << r.case_name << ',' << r.method << ',' << r.threads << ',' << r.status << ','
      << Num(r.wall_s) << ',' << r.iterations << ',' << r.steps << ',' << r.np << ',' << r.sequences
      << ',' << r.samples << ',' << Num(r.t_step_us) << ',' << Num(r.floor_ratio) << ','
      << Num(r.initial_cost, "%.10g") << ',' << Num(r.final_cost, "%.10g") << ','
      << Num(r.max_rel_error) << ',' << Num(r.rms_rel_error) << ',' << note << ','
      << Num(r.others_cores, "%.3f") << ',' << Num(r.load1, "%.2f") << ',' << (r.idle ? 1 : 0)
      << ',' << Num(r.path_t_step_us) << ',' << Num(r.path_floor_ratio) << ','
      << Num(r.host_slowness, "%.3f") << ',' << r.attempts << '\n';
  }
  io::WriteFileAtomically(path, f.str());
}

// the table as Markdown (BENCHMARKS.md is made from it)
void WriteMarkdown(const std::string& path, const std::vector<Row>& rows,
                   const std::vector<Ratio>& ratios) {
  std::ostringstream f;
  f << "| case | method | threads | status | wall [s] | iterations | sim steps | final cost | "
       "max rel. error | time/iteration / floor | / path floor | note |\n"
    << "| --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- |\n";
  for (const Row& r : rows) {
    f << "| " << r.case_name << " | " << r.method << " | " << r.threads << " | " << r.status
      << " | " << Num(r.wall_s, "%.3f") << " | " << r.iterations << " | " << r.steps << " | "
      << Num(r.final_cost, "%.6g") << " | " << Num(r.max_rel_error, "%.2e") << " | "
      << Num(r.floor_ratio, "%.2f") << " | " << Num(r.path_floor_ratio, "%.2f") << " | " << r.note
      << " |\n";
  }
  f << "\nOurs against the best peer at equal threads (speed-up = peer wall / our wall):\n\n"
    << "| case | threads | ours (fastest) | wall [s] | iterations | best peer | wall [s] | "
       "speed-up | peer's fewest iterations | load |\n"
    << "| --- | --- | --- | --- | --- | --- | --- | --- | --- | --- |\n";
  for (const Ratio& q : ratios) f << "| " << RatioLine(q, " | ") << " |\n";
  io::WriteFileAtomically(path, f.str());
}

std::string Machine() {
  std::ifstream cpu("/proc/cpuinfo");
  std::string line;
  while (std::getline(cpu, line)) {
    if (line.rfind("model name", 0) == 0) return line.substr(line.find(':') + 2);
  }
  return "unknown";
}

// the rows with the machine, versions and command; non-finite numbers as null
void WriteJson(const std::string& path, const std::vector<Row>& rows,
               const std::vector<Ratio>& ratios, const std::string& command) {
  char date[32];
  const std::time_t now = std::time(nullptr);
  std::strftime(date, sizeof(date), "%Y-%m-%dT%H:%M:%SZ", std::gmtime(&now));
  nlohmann::ordered_json j;
  j["tool"] = "bench_fit";
  j["created"] = date;
  j["command"] = command;
  j["machine"] = {{"cpu", Machine()}, {"hardware_threads", std::thread::hardware_concurrency()}};
  j["versions"] = {{"mjsysid", MJSYSID_VERSION},
                   {"mujoco", mj_versionString()},
                   {"ceres", CERES_VERSION_STRING},
                   {"compiler", MJSYSID_COMPILER},
                   {"build_type", MJSYSID_BUILD_TYPE}};
  j["rows"] = nlohmann::ordered_json::array();
  for (const Row& r : rows) {
    nlohmann::ordered_json estimates = nlohmann::ordered_json::object();
    for (const auto& [name, value] : r.estimates) estimates[name] = value;
    j["rows"].push_back({{"case", r.case_name},
                         {"method", r.method},
                         {"threads", r.threads},
                         {"status", r.status},
                         {"wall_s", r.wall_s},
                         {"iterations", r.iterations},
                         {"sim_steps", r.steps},
                         {"np", r.np},
                         {"sequences", r.sequences},
                         {"samples", r.samples},
                         {"t_step_us", r.t_step_us},
                         {"floor_ratio", r.floor_ratio},
                         {"path_t_step_us", r.path_t_step_us},
                         {"path_floor_ratio", r.path_floor_ratio},
                         {"initial_cost", r.initial_cost},
                         {"final_cost", r.final_cost},
                         {"max_rel_error", r.max_rel_error},
                         {"rms_rel_error", r.rms_rel_error},
                         {"note", r.note},
                         {"others_cores", r.others_cores},
                         {"load1", r.load1},
                         {"idle", r.idle},
                         {"runs", r.runs},
                         {"host_slowness", r.host_slowness},
                         {"attempts", r.attempts},
                         {"estimates", estimates}});
  }
  j["ratios"] = nlohmann::ordered_json::array();
  for (const Ratio& q : ratios) {
    j["ratios"].push_back({{"case", q.case_name},
                           {"threads", q.threads},
                           {"ours", q.ours->method},
                           {"ours_wall_s", q.ours->wall_s},
                           {"ours_iterations", q.ours->iterations},
                           {"peer", q.peer ? q.peer->method : ""},
                           {"peer_wall_s", q.peer ? q.peer->wall_s : NAN},
                           {"speedup", q.speedup},
                           {"peer_fewest_iterations", q.peer_fewest_iterations}});
  }
  io::WriteFileAtomically(path, j.dump(2) + "\n");
}

// error against time, one log-log panel per case; a point per method that finished
void WriteSvg(const std::string& path, const std::vector<std::string>& cases,
              const std::vector<Row>& rows) {
  const int cols = 2, pw = 520, ph = 300, ml = 70, mb = 40, mt = 30, mr = 190;
  const int nrows = (static_cast<int>(cases.size()) + cols - 1) / cols;
  std::ostringstream f;
  f << "<svg xmlns=\"http://www.w3.org/2000/svg\" width=\"" << cols * pw << "\" height=\""
    << nrows * ph << "\" font-family=\"sans-serif\" font-size=\"10\">\n"
    << "<rect width=\"100%\" height=\"100%\" fill=\"white\"/>\n";
  auto color = [](const std::string& m) {
    if (m.rfind("ours/directional", 0) == 0) return "#1f77b4";
    if (m.rfind("ours/matrix", 0) == 0) return "#2ca02c";
    if (m.rfind("oracle", 0) == 0) return "#9467bd";
    if (m.rfind("ceres", 0) == 0) return "#ff7f0e";
    return "#d62728";
  };
  for (size_t ci = 0; ci < cases.size(); ++ci) {
    const int x0 = static_cast<int>(ci % cols) * pw, y0 = static_cast<int>(ci / cols) * ph;
    std::vector<const Row*> pts;
    for (const Row& r : rows) {
      if (r.case_name == cases[ci] && std::isfinite(r.wall_s) && std::isfinite(r.max_rel_error))
        pts.push_back(&r);
    }
    f << "<text x=\"" << x0 + ml << "\" y=\"" << y0 + 18 << "\" font-size=\"13\">" << cases[ci]
      << ": max relative parameter error vs wall time</text>\n";
    if (pts.empty()) continue;
    double tmin = INFINITY, tmax = 0, emin = INFINITY, emax = 0;
    for (const Row* r : pts) {
      tmin = std::min(tmin, r->wall_s);
      tmax = std::max(tmax, r->wall_s);
      const double e = std::max(r->max_rel_error, 1e-12);
      emin = std::min(emin, e);
      emax = std::max(emax, e);
    }
    const double lt0 = std::floor(std::log10(tmin)), lt1 = std::ceil(std::log10(tmax) + 1e-9);
    const double le0 = std::floor(std::log10(emin)), le1 = std::ceil(std::log10(emax) + 1e-9);
    const int w = pw - ml - mr, h = ph - mt - mb;
    auto X = [&](double t) { return x0 + ml + (std::log10(t) - lt0) / (lt1 - lt0) * w; };
    auto Y = [&](double e) {
      return y0 + mt + h - (std::log10(std::max(e, 1e-12)) - le0) / std::max(le1 - le0, 1.0) * h;
    };
    f << "<rect x=\"" << x0 + ml << "\" y=\"" << y0 + mt << "\" width=\"" << w << "\" height=\""
      << h << "\" fill=\"none\" stroke=\"#888\"/>\n";
    for (double d = lt0; d <= lt1; d += 1) {
      f << "<text x=\"" << X(std::pow(10, d)) - 10 << "\" y=\"" << y0 + mt + h + 14 << "\">1e" << d
        << "</text>\n";
    }
    for (double d = le0; d <= std::max(le1, le0 + 1); d += 1) {
      f << "<text x=\"" << x0 + 30 << "\" y=\"" << Y(std::pow(10, d)) + 3 << "\">1e" << d
        << "</text>\n";
    }
    f << "<text x=\"" << x0 + ml + w / 2 - 30 << "\" y=\"" << y0 + ph - 8
      << "\">wall time [s]</text>\n";
    int legend = 0;
    for (const Row* r : pts) {
      const double x = X(r->wall_s), y = Y(r->max_rel_error);
      f << "<circle cx=\"" << x << "\" cy=\"" << y << "\" r=\"4\" fill=\"" << color(r->method)
        << "\" fill-opacity=\"0.7\"/>\n";
      f << "<text x=\"" << x0 + ml + w + 8 << "\" y=\"" << y0 + mt + 10 + 12 * legend++
        << "\" fill=\"" << color(r->method) << "\">" << r->method << " " << r->threads
        << "t: " << Num(r->wall_s, "%.3g") << " s, " << Num(r->max_rel_error, "%.1e")
        << "</text>\n";
    }
  }
  f << "</svg>\n";
  io::WriteFileAtomically(path, f.str());
}

std::vector<std::string> Split(const std::string& s) {
  std::vector<std::string> out;
  std::stringstream ss(s);
  std::string item;
  while (std::getline(ss, item, ',')) {
    if (!item.empty()) out.push_back(item);
  }
  return out;
}

int Main(int argc, char** argv) {
  CLI::App app{"bench_fit: run time against parameter error of whole fits, per method"};
  std::string cases_arg =
      "spring_mass,pendulum,double_pendulum,cartpole,arm5,box_floor,humanoid,arm7";
  std::string methods_arg = "ours,auto,full,oracle,numdiff,peer";
  std::string out_dir = "results/bench", peer_dir, experiments = MJSYSID_EXPERIMENTS_DIR;
  std::vector<std::string> caps;
  std::string ours_arg;
  double idle_wait = 30;
  int repeats = 5;
  double repeat_budget = 1.5;
  app.add_option("--cases", cases_arg, "comma-separated experiment names")->capture_default_str();
  app.add_option("--methods", methods_arg,
                 "comma-separated: ours, auto (ours from initial: auto), oracle, numdiff, peer, "
                 "full (ours directional forward without the reduced model, 1 and 2 threads)")
      ->capture_default_str();
  app.add_option("--out", out_dir, "output folder")->capture_default_str();
  app.add_option("--peer-dir", peer_dir, "folder of the peer driver's results (<case>-<n>t/)");
  app.add_option("--experiments", experiments, "folder of the experiment files")
      ->capture_default_str();
  app.add_option("--ours", ours_arg,
                 "comma-separated configurations of ours to run, e.g. "
                 "directional/forward/1,matrix/central/2 (default: all eight)");
  app.add_option("--idle-wait", idle_wait,
                 "seconds to wait before each row for other processes to leave the cores it "
                 "needs (<= 0.5 busy core per thread of the row); rows that still are not idle say "
                 "so in their note")
      ->capture_default_str();
  app.add_option("--repeats", repeats,
                 "runs per row of ours and numeric diff: the fastest is the row's wall time "
                 "(repeated while the runs add up to less than --repeat-budget seconds)")
      ->capture_default_str()
      ->check(CLI::PositiveNumber);
  app.add_option("--repeat-budget", repeat_budget, "seconds of fitting per row that allow a repeat")
      ->capture_default_str();
  app.add_option("--max-iterations", caps, "per-case iteration cap, e.g. humanoid=10");
  bool print_ledger = false;
  app.add_flag(
      "--ledger", print_ledger,
      "print under each row of ours its fit's steps and time by phase (sysid/fit_ledger.h)");
  CLI11_PARSE(app, argc, argv);
  std::string command;
  for (int i = 0; i < argc; ++i) command += (i ? " " : "") + std::string(argv[i]);

  InstallMujocoHandlers();
  std::map<std::string, int> cap;
  for (const std::string& c : caps) {
    const size_t eq = c.find('=');
    char* end = nullptr;
    const long n = eq == std::string::npos ? 0 : std::strtol(c.c_str() + eq + 1, &end, 10);
    if (eq == std::string::npos || end == c.c_str() + eq + 1 || *end != '\0' || n <= 0) {
      std::fprintf(stderr, "bench_fit: --max-iterations expects case=N with N > 0, got '%s'\n",
                   c.c_str());
      return 2;
    }
    cap[c.substr(0, eq)] = static_cast<int>(n);
  }
  const std::vector<std::string> cases = Split(cases_arg), methods = Split(methods_arg);
  const std::vector<std::string> ours = Split(ours_arg);
  auto want = [&](const char* m) {
    return std::find(methods.begin(), methods.end(), m) != methods.end();
  };
  fs::create_directories(out_dir);
  std::printf("machine: %s, %u hardware threads; MuJoCo %s, Ceres %s, mjsysid %s (%s)\n",
              Machine().c_str(), std::thread::hardware_concurrency(), mj_versionString(),
              CERES_VERSION_STRING, MJSYSID_VERSION, MJSYSID_BUILD_TYPE);
  std::printf("%-16s %-28s %2s %-10s %9s %5s %12s %11s %11s %10s %8s %8s  %s\n", "case", "method",
              "th", "status", "wall [s]", "iter", "sim steps", "final cost", "max rel err",
              "rms rel", "/floor", "/path", "note");
  std::vector<Row> rows;
  for (const std::string& name : cases) {
    Case c;
    try {
      c = LoadCase(experiments, name);
      Row load;
      WaitForIdle(1, idle_wait, &load);
      if (!load.idle)
        std::printf("%s: step time measured %s\n", name.c_str(), LoadNote(load).c_str());
      MeasureStep(&c);
    } catch (const std::exception& e) {
      std::fprintf(stderr, "bench_fit: case %s: %s\n", name.c_str(), e.what());
      return 2;
    }
    const int max_it = cap.count(name) ? cap[name] : 0;
    const size_t first_row = rows.size();
    const double first_t_step_us = c.t_step * 1e6;
    // one measurement of a row: the load checked (and waited for) and the host probed first, the
    // fastest of up to --repeats runs, repeated while their wall time adds up to less than
    // --repeat-budget seconds (the same rule as the peer driver's --repeats), the host probed after
    auto measure_once = [&](int threads, const std::function<Row()>& fit) {
      Row before;
      WaitForIdle(threads, idle_wait, &before);
      const double slow_before = HostSlowness(&c);
      Row r = fit();
      double spent = r.wall_s;
      for (int k = 1; k < repeats && std::isfinite(spent) && spent < repeat_budget; ++k) {
        Row again = fit();
        spent += again.wall_s;
        if (again.iterations != r.iterations || again.steps != r.steps ||
            again.estimates != r.estimates) {
          r.note += std::string(r.note.empty() ? "" : "; ") +
                    "a repeated run differed (iterations, steps or estimates)";
          break;
        }
        ++r.runs;
        if (again.wall_s < r.wall_s) {
          again.runs = r.runs;
          again.note = r.note;
          r = std::move(again);
        }
      }
      r.others_cores = before.others_cores;
      r.load1 = before.load1;
      r.idle = before.idle;
      r.host_slowness = std::max(slow_before, HostSlowness(&c));
      return r;
    };
    // a row measured while the host ran slow (HostSlowness above kSteadyHost before or after it)
    // is measured again, up to kMaxAttempts times in all, kHostWait seconds apart; the first
    // steady attempt stays, else the fastest, which then says the host was slow around it
    auto measure = [&](int threads, const std::function<Row()>& fit) {
      Row r = measure_once(threads, fit);
      for (int a = 1; a < kMaxAttempts && r.host_slowness > kSteadyHost; ++a) {
        std::this_thread::sleep_for(std::chrono::duration<double>(kHostWait));
        Row again = measure_once(threads, fit);
        again.attempts = r.attempts + 1;
        if (again.wall_s < r.wall_s || again.host_slowness <= kSteadyHost) {
          r = std::move(again);
        } else {
          r.attempts = again.attempts;
        }
      }
      if (r.host_slowness > kSteadyHost) {
        r.note += std::string(r.note.empty() ? "" : "; ") + "host slow: probe " +
                  Num(r.host_slowness, "%.2f") + "x the case's fastest";
      }
      return r;
    };
    auto add = [&](Row r) {
      const std::string load = LoadNote(r);
      if (!load.empty()) r.note += (r.note.empty() ? "" : "; ") + load;
      r.case_name = name;
      r.sequences = c.sequences;
      r.samples = c.samples;
      Errors(c, &r);
      Floor(&c, &r);
      PrintRow(r);
      if (print_ledger && std::isfinite(r.cpu_s)) {
        std::printf("  process CPU time during the fit: %.4f s\n", r.cpu_s);
      }
      if (print_ledger && !r.path.empty()) {
        std::printf(
            "  t_step on the path: first iterate %.3f us, last %.3f us, mean %.3f us (the "
            "case's t_step %.3f us)\n",
            RelativeStepTimeAt(&c, r.path.front()) * c.t_step * 1e6,
            RelativeStepTimeAt(&c, r.path.back()) * c.t_step * 1e6, r.path_t_step_us, r.t_step_us);
      }
      if (print_ledger && !r.ledger.empty()) {
        std::printf("  ledger (model loading and log reading before the fit: %.4f s):\n%s",
                    r.build_s, FormatLedger(r.ledger, r.samples).c_str());
      }
      rows.push_back(std::move(r));
      WriteCsv(out_dir + "/fit_bench.csv", rows);  // each row on disk as soon as it exists
    };
    if (want("ours")) {
      for (JacobianMode mode : {JacobianMode::kDirectional, JacobianMode::kMatrix}) {
        for (bool central : {false, true}) {
          for (int threads : {1, 2}) {
            const std::string m =
                std::string("ours/") + JacobianModeName(mode) + (central ? "/central" : "/forward");
            const std::string config = m.substr(5) + "/" + std::to_string(threads);
            if (!ours.empty() && std::find(ours.begin(), ours.end(), config) == ours.end())
              continue;
            add(measure(threads, [&] { return FitOurs(c, m, mode, central, threads, max_it); }));
          }
        }
      }
    }
    if (want("auto")) {
      // the equation-error start: every parameter `initial: auto`, directional forward, 1 and 2
      // threads
      for (int threads : {1, 2}) {
        add(measure(threads, [&] {
          return FitOurs(c, "ours/directional/forward+auto", JacobianMode::kDirectional, false,
                         threads, max_it, true);
        }));
      }
    }
    if (want("full")) {
      // the reduced model's share: ours directional forward on the model as given
      for (int threads : {1, 2}) {
        add(measure(threads, [&] {
          return FitOurs(c, "full-model/directional/forward", JacobianMode::kDirectional, false,
                         threads, max_it, false, false);
        }));
      }
    }
    if (want("oracle")) {
      add(measure(2, [&] {
        return FitOurs(c, "oracle/whole/forward", JacobianMode::kWholeRollout, false, 2, max_it);
      }));
    }
    if (want("numdiff")) add(measure(1, [&] { return FitNumDiff(c, max_it); }));
    if (want("peer")) {
      for (int threads : {1, 2}) {
        add(PeerRow(c, peer_dir + "/" + name + "-" + std::to_string(threads) + "t", threads,
                    "mujoco.sysid"));
      }
      add(PeerRow(c, peer_dir + "/" + name + "-phys-2t", 2, "mujoco.sysid/physical"));
    }
    // the floors again with the case's t_step as it ends (the fastest of every probe of the case)
    if (c.t_step * 1e6 < first_t_step_us * 0.99) {
      std::printf(
          "%s: t_step %.4f -> %.4f us by a later probe: its rows' floor ratios in the "
          "files use the latter\n",
          name.c_str(), first_t_step_us, c.t_step * 1e6);
    }
    for (size_t i = first_row; i < rows.size(); ++i) Floor(&c, &rows[i]);
    WriteCsv(out_dir + "/fit_bench.csv", rows);
  }
  const std::vector<Ratio> ratios = Ratios(cases, rows);
  std::printf(
      "\nours against the best peer at equal threads (speed-up = peer wall / our wall)\n"
      "case,threads,ours,wall_s,iterations,peer,peer_wall_s,speedup,peer_fewest_iterations,"
      "load\n");
  for (const Ratio& q : ratios) std::printf("%s\n", RatioLine(q, ",").c_str());
  WriteMarkdown(out_dir + "/fit_bench.md", rows, ratios);
  WriteJson(out_dir + "/fit_bench.json", rows, ratios, command);
  WriteSvg(out_dir + "/error_vs_time.svg", cases, rows);
  std::printf("wrote %s/{fit_bench.csv, fit_bench.json, fit_bench.md, error_vs_time.svg}\n",
              out_dir.c_str());
  return 0;
}

}  // namespace
}  // namespace mjsysid

int main(int argc, char** argv) { return mjsysid::Main(argc, argv); }
