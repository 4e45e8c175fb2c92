// bench_fit: the methods' fits. Ours (Problem::Fit with one Jacobian setting), the hand-written
// Ceres numeric-diff baseline, and the peer's rows read from its driver's JSON.
#include <ceres/ceres.h>
#include <mujoco/mujoco.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <string>
#include <utility>
#include <vector>

#include "core/mujoco_env.h"
#include "core/parameters.h"
#include "core/state.h"
#include "sysid/problem.h"
#include "tools/bench/fit_bench.h"

namespace mjsysid {
namespace bench {
namespace {

namespace fs = std::filesystem;

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

// j[key] into *out when it is a number
bool JsonNumber(const nlohmann::json& j, const char* key, double* out) {
  const auto it = j.find(key);
  if (it == j.end() || !it->is_number()) return false;
  *out = it->get<double>();
  return true;
}

}  // namespace

Row FitOurs(const Case& c, const std::string& method, JacobianMode mode, bool central, int threads,
            int max_iterations, bool auto_start, bool reduce, bool subset) {
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
  o.subset_start = subset;
  if (max_iterations > 0) o.max_iterations = max_iterations;
  row.np = static_cast<int>(b.parameters.size());
  try {
    const double cpu0 = ProcessCpuSeconds();
    const FitResult r = b.problem->Fit(o);
    row.cpu_s = ProcessCpuSeconds() - cpu0;
    row.wall_s = r.seconds;
    row.iterations = r.iterations;
    row.steps = r.diagnostics.simulation_steps;
    row.ledger = r.diagnostics.ledger;
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

}  // namespace bench
}  // namespace mjsysid
