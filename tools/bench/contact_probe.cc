// bench_contact_probe: why a contact-rich fit fails, measured on an experiment and its log
// (docs/numerics.md, "Contact: cost surface and Jacobians").
//
// For a single-model experiment (EXP.yaml and its `data:` log) at a point in parameter space
// (--at truth | start | v1,v2,...), with the fit's sensors and weights (1/sigma), it prints:
// - the plain cost 0.5 |r|^2 (no robust loss), sum(r^2) / m, the contact events of the nominal
//   rollouts (steps with contacts, changes of the contact count) and the constraint solves that
//   stopped at opt.iterations;
// - with --jacobians: per parameter, the core's residual Jacobian column (directional and matrix,
//   forward and central, relative_step 1e-6) against whole-rollout central differences of the
//   residuals at relative steps 1e-2 .. 1e-8: relative column error |J - J_fd| / |J_fd| and the
//   cost slope d cost / d log p;
// - with --scan N --span S: the cost at p_j (1 + d) for N points d in [-S, S] per parameter
//   (a 1-D cut through the truth or the point), and the roughness of that cut: the largest
//   |second difference| over the points against what a quadratic through the ends predicts.
// - with --segments N: every rollout restarts from the log's qpos/qvel every N steps (the cost of
//   multiple shooting with its segment states on the data; 0: whole sequences);
// - with --line K: the cost per fitted sensor at K points along the straight line from the start
//   (t = 0) to the truth (t = 1): sum(r^2)/m of that sensor at both ends, and its ruggedness
//   along the line, the total variation of its cost over its net fall |c(0) - c(1)| (1: it falls
//   monotonically towards the truth; >> 1: it jumps up and down on the way).
// A missing log is simulated from the experiment's `simulate:` block (--write-log).
// MuJoCo options of the model can be changed for the probe: --tolerance (the solver tolerance the
// core uses, default 1e-10), --fixed-iterations, --iterations, --noslip, --elliptic, --integrator.
#include <mujoco/mujoco.h>

#include <CLI/CLI.hpp>
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <exception>
#include <filesystem>
#include <map>
#include <sstream>
#include <string>
#include <vector>

#include "core/mujoco_env.h"
#include "core/simulator.h"
#include "sysid/io/experiment.h"
#include "sysid/io/log.h"
#include "sysid/run/fit_experiment.h"
#include "sysid/sim/simulate.h"

namespace mjsysid {
namespace {

// one fitted sensor column of one sequence: where it sits in sensordata, its weight and sensor
struct Column {
  int col = 0;
  double weight = 1;
  int sensor = 0;  // index into Probe::sensor_names()
};

// the fit's residuals (weighted, no robust loss) of every sequence at given parameter values
class Probe {
 public:
  // segment_steps > 0: each sequence cut into pieces of that many steps, each started from the
  // log's qpos/qvel at its first sample (the log on the simulation grid, as `simulate` writes it)
  Probe(const run::BuiltProblem& built, const mjModel& m, const SimulatorOptions& so,
        int segment_steps)
      : sim_(m, Specs(built), so) {
    for (const FitSequence& s : built.sequences) {
      std::vector<Column> cols;
      for (const std::string& name : s.sensors) {
        const int id = mj_name2id(&m, mjOBJ_SENSOR, name.c_str());
        const auto w = built.options.sensor_weights.find(name);
        const double weight = w != built.options.sensor_weights.end() ? w->second : 1.0;
        const auto at = std::find(sensor_names_.begin(), sensor_names_.end(), name);
        const int index = static_cast<int>(at - sensor_names_.begin());
        if (at == sensor_names_.end()) sensor_names_.push_back(name);
        for (int i = 0; i < m.sensor_dim[id]; ++i) {
          cols.push_back({m.sensor_adr[id] + i, weight, index});
        }
      }
      const int T = static_cast<int>(s.ctrl.rows());
      const int len = segment_steps > 0 ? segment_steps : T;
      for (int k0 = 0; k0 < T; k0 += len) {
        const int n = std::min(len, T - k0);
        InitialState x0 = s.x0;
        if (k0 > 0) {
          if (s.qpos.rows() <= k0 || s.qvel.rows() <= k0) {
            throw std::invalid_argument("--segments needs the log's qpos and qvel");
          }
          x0.qpos = s.qpos.row(k0).transpose();
          x0.qvel = s.qvel.row(k0).transpose();
          x0.time = s.x0.time + k0 * m.opt.timestep;
        }
        inputs_.push_back(SequenceInput{x0, s.ctrl.middleRows(k0, n)});
        measured_.push_back(s.measured.middleRows(k0, n));
        columns_.push_back(cols);
      }
    }
  }

  const std::vector<std::string>& sensor_names() const { return sensor_names_; }

  // 0.5 sum(r^2) and the number of rows per fitted sensor (sensor_names order) at p
  void CostPerSensor(const Eigen::VectorXd& p, std::vector<double>* cost,
                     std::vector<long long>* rows) {
    std::vector<Trajectory> trajectories;
    sim_.SetParameters(p);
    sim_.Rollout(inputs_, &trajectories);
    cost->assign(sensor_names_.size(), 0.0);
    rows->assign(sensor_names_.size(), 0);
    for (size_t s = 0; s < inputs_.size(); ++s) {
      const Trajectory& t = trajectories[s];
      for (int k = 0; k < t.T; ++k) {
        for (const Column& c : columns_[s]) {
          const double r = c.weight * (t.sensors(k, c.col) - measured_[s](k, c.col));
          if (!std::isfinite(r)) continue;
          (*cost)[c.sensor] += 0.5 * r * r;
          ++(*rows)[c.sensor];
        }
      }
    }
  }

  Simulator& sim() { return sim_; }
  const std::vector<SequenceInput>& inputs() const { return inputs_; }

  // the residual vector at p (sequence by sequence, sample by sample, column by column)
  Eigen::VectorXd Residuals(const Eigen::VectorXd& p, std::vector<Trajectory>* trajectories) {
    sim_.SetParameters(p);
    sim_.Rollout(inputs_, trajectories);
    long long n = 0;
    for (size_t s = 0; s < inputs_.size(); ++s)
      n +=
          static_cast<long long>((*trajectories)[s].T) * static_cast<long long>(columns_[s].size());
    Eigen::VectorXd r(n);
    Eigen::Index i = 0;
    for (size_t s = 0; s < inputs_.size(); ++s) {
      const Trajectory& t = (*trajectories)[s];
      for (int k = 0; k < t.T; ++k) {
        for (const Column& c : columns_[s]) {
          r[i++] = c.weight * (t.sensors(k, c.col) - measured_[s](k, c.col));
        }
      }
    }
    return r;
  }

  // the residual Jacobian (rows as Residuals) from the core's sensor Jacobians
  Eigen::MatrixXd ResidualJacobian(const std::vector<Trajectory>& nominal,
                                   const JacobianOptions& opt, int* kinks,
                                   std::vector<std::string>* warnings) {
    std::vector<Sensitivity> sens;
    sim_.Jacobians(inputs_, nominal, opt, &sens);
    long long n = 0;
    for (size_t s = 0; s < inputs_.size(); ++s)
      n += static_cast<long long>(nominal[s].T) * static_cast<long long>(columns_[s].size());
    const int np = static_cast<int>(sim_.GetParameters().size());
    Eigen::MatrixXd J(n, np);
    Eigen::Index i = 0;
    const int ns = sim_.model().nsensordata;
    *kinks = 0;
    for (size_t s = 0; s < inputs_.size(); ++s) {
      *kinks += sens[s].kinks;
      for (const std::string& w : sens[s].warnings) warnings->push_back(w);
      for (int k = 0; k < nominal[s].T; ++k) {
        for (const Column& c : columns_[s]) {
          J.row(i++) = c.weight * sens[s].DyDp.row(static_cast<Eigen::Index>(k) * ns + c.col);
        }
      }
    }
    return J;
  }

 private:
  static std::vector<ParameterSpec> Specs(const run::BuiltProblem& built) {
    std::vector<ParameterSpec> specs;
    for (const FitParameter& p : built.parameters) specs.push_back(p.target);
    return specs;
  }

  Simulator sim_;
  std::vector<std::string> sensor_names_;
  std::vector<SequenceInput> inputs_;
  std::vector<RowMatrix> measured_;
  std::vector<std::vector<Column>> columns_;
};

// contact events and capped solves of nominal rollouts
void PrintRolloutStats(const std::vector<Trajectory>& tr) {
  long long steps = 0, with_contact = 0, changes = 0;
  SolverStats solver;
  for (const Trajectory& t : tr) {
    for (int k = 0; k < t.T; ++k) {
      ++steps;
      with_contact += t.ncon[k] > 0;
      if (k > 0 && t.ncon[k] != t.ncon[k - 1]) ++changes;
    }
    solver += t.solver;
  }
  std::printf(
      "  steps %lld, with contacts %lld, contact-count changes %lld, solves %d, capped %d\n", steps,
      with_contact, changes, solver.solved, solver.capped);
}

// the command line
struct Args {
  std::string exp_path, at = "truth";
  bool jacobians = false, fixed = false, elliptic = false;
  int scan = 0, iterations = -1, noslip = -1, segments = 0, line = 0;
  bool write_log = false;
  double span = 1e-3, tolerance = 1e-10;
  std::string integrator;
};

void AddOptions(CLI::App* app, Args* a) {
  app->add_option("experiment", a->exp_path, "EXP.yaml")->required();
  app->add_option("--at", a->at, "truth | start | comma-separated values");
  app->add_flag("--jacobians", a->jacobians,
                "compare the core's Jacobians with central differences");
  app->add_option("--scan", a->scan, "points per parameter of a 1-D cost cut (0: none)");
  app->add_option("--span", a->span, "relative half-width of the cut");
  app->add_option("--tolerance", a->tolerance,
                  "the core's solver tolerance (min with the model's)");
  app->add_flag("--fixed-iterations", a->fixed, "tolerance 0: opt.iterations every step");
  app->add_option("--iterations", a->iterations, "opt.iterations");
  app->add_option("--noslip", a->noslip, "opt.noslip_iterations");
  app->add_flag("--elliptic", a->elliptic, "elliptic friction cones");
  app->add_option("--integrator", a->integrator, "euler | implicitfast | rk4 | implicit");
  app->add_option("--segments", a->segments,
                  "restart rollouts from the log's states every N steps");
  app->add_option("--line", a->line, "points of the per-sensor cost from the start to the truth");
  app->add_flag("--write-log", a->write_log, "simulate the experiment's log when it is missing");
}

// the solver options of the command line written into the model
void ApplySolverOptions(const Args& a, mjModel* mp) {
  mjModel& m = *mp;
  if (a.iterations > 0) m.opt.iterations = a.iterations;
  if (a.noslip >= 0) m.opt.noslip_iterations = a.noslip;
  if (a.elliptic) m.opt.cone = mjCONE_ELLIPTIC;
  if (a.integrator == "euler") m.opt.integrator = mjINT_EULER;
  if (a.integrator == "implicitfast") m.opt.integrator = mjINT_IMPLICITFAST;
  if (a.integrator == "implicit") m.opt.integrator = mjINT_IMPLICIT;
  if (a.integrator == "rk4") m.opt.integrator = mjINT_RK4;
}

// the point: the truth, the start, or given values
Eigen::VectorXd ThePoint(const run::BuiltProblem& built, const io::ExperimentConfig& cfg,
                         const std::string& at) {
  const int np = static_cast<int>(built.parameters.size());
  Eigen::VectorXd p(np);
  for (int j = 0; j < np; ++j) {
    p[j] = built.parameters[j].initial;
    if (at == "truth") {
      for (const io::NamedValue& v : cfg.simulate.truth)
        if (v.name == built.parameters[j].name) p[j] = v.value;
    }
  }
  if (at != "truth" && at != "start") {
    std::stringstream ss(at);
    std::string item;
    for (int j = 0; j < np && std::getline(ss, item, ','); ++j) p[j] = std::stod(item);
  }
  return p;
}

// the core's Jacobians in each mode against whole-rollout central differences of the residuals
// at several relative steps, as gradients of the cost and per-parameter relative differences
void CompareJacobians(Probe* probe, const run::BuiltProblem& built, const Eigen::VectorXd& p,
                      const Eigen::VectorXd& r0, std::vector<Trajectory>* nominal_out) {
  const int np = static_cast<int>(p.size());
  std::vector<Trajectory>& nominal = *nominal_out;
  // whole-rollout central differences of the residuals at several relative steps
  const std::vector<double> steps = {1e-2, 1e-3, 1e-4, 1e-5, 1e-6, 1e-7, 1e-8};
  std::vector<Eigen::MatrixXd> fd;
  for (double h : steps) {
    Eigen::MatrixXd J(r0.size(), np);
    for (int j = 0; j < np; ++j) {
      Eigen::VectorXd pp = p, pm = p;
      pp[j] *= 1 + h;
      pm[j] *= 1 - h;
      std::vector<Trajectory> tmp;
      J.col(j) = (probe->Residuals(pp, &tmp) - probe->Residuals(pm, &tmp)) / (2 * h * p[j]);
    }
    fd.push_back(J);
  }
  probe->Residuals(p, &nominal);
  std::printf("  d cost / d log p (whole-rollout central, relative step h):\n");
  for (size_t i = 0; i < steps.size(); ++i) {
    const Eigen::VectorXd g = fd[i].transpose() * r0;
    std::printf("    h %-6.0e", steps[i]);
    for (int j = 0; j < np; ++j) std::printf(" %14.6g", g[j] * p[j]);
    std::printf("\n");
  }
  const struct {
    JacobianMode mode;
    bool central;
  } modes[] = {{JacobianMode::kDirectional, false},
               {JacobianMode::kDirectional, true},
               {JacobianMode::kMatrix, false},
               {JacobianMode::kMatrix, true}};
  for (const auto& md : modes) {
    JacobianOptions jo;
    jo.mode = md.mode;
    jo.central = md.central;
    jo.state_jacobians = false;
    int kinks = 0;
    std::vector<std::string> warnings;
    const Eigen::MatrixXd J = probe->ResidualJacobian(nominal, jo, &kinks, &warnings);
    const Eigen::VectorXd g = J.transpose() * r0;
    std::printf("  core %s %s: kinks %d, d cost / d log p", JacobianModeName(md.mode),
                md.central ? "central" : "forward", kinks);
    for (int j = 0; j < np; ++j) std::printf(" %14.6g", g[j] * p[j]);
    std::printf("\n    |J - J_fd(h)| / |J_fd(h)| per parameter, h = 1e-2 .. 1e-8:\n");
    for (int j = 0; j < np; ++j) {
      std::printf("    %-18s", built.parameters[j].name.c_str());
      for (const Eigen::MatrixXd& F : fd)
        std::printf(" %9.2e", (J.col(j) - F.col(j)).norm() / F.col(j).norm());
      std::printf("\n");
    }
    for (const std::string& w : warnings) std::printf("    warning: %s\n", w.c_str());
  }
}

// the cost per sensor along the line from the start (t = 0) to the truth (t = 1)
void CostLine(Probe* probe, const run::BuiltProblem& built, const io::ExperimentConfig& cfg,
              int line, int segments) {
  const int np = static_cast<int>(built.parameters.size());
  Eigen::VectorXd start(np), truth(np);
  for (int j = 0; j < np; ++j) {
    start[j] = truth[j] = built.parameters[j].initial;
    for (const io::NamedValue& v : cfg.simulate.truth)
      if (v.name == built.parameters[j].name) truth[j] = v.value;
  }
  const size_t ns = probe->sensor_names().size();
  std::vector<std::vector<double>> c(ns, std::vector<double>(line));
  std::vector<long long> rows;
  std::vector<double> cost;
  for (int i = 0; i < line; ++i) {
    const double t = static_cast<double>(i) / (line - 1);
    probe->CostPerSensor(start + t * (truth - start), &cost, &rows);
    for (size_t k = 0; k < ns; ++k) c[k][i] = cost[k];
  }
  std::printf(
      "  line start -> truth, %d points, segments %d (sensor: sum(r^2)/m at start, at "
      "truth; total variation / net fall):\n",
      line, segments);
  for (size_t k = 0; k < ns; ++k) {
    double tv = 0;
    for (int i = 1; i < line; ++i) tv += std::abs(c[k][i] - c[k][i - 1]);
    const double fall = std::abs(c[k][0] - c[k][line - 1]);
    const double m_rows = static_cast<double>(std::max(rows[k], 1LL));
    std::printf("    %-18s %11.4g %11.4g %9.3g\n", probe->sensor_names()[k].c_str(),
                2 * c[k][0] / m_rows, 2 * c[k][line - 1] / m_rows, fall > 0 ? tv / fall : 0.0);
  }
}

// 1-D cuts of the cost through p, with their roughness
void CostCuts(Probe* probe, const run::BuiltProblem& built, const Eigen::VectorXd& p,
              const Eigen::VectorXd& r0, int scan, double span) {
  const int np = static_cast<int>(p.size());
  for (int j = 0; j < np && scan > 1; ++j) {
    std::printf("  cut along %s (relative offset d, cost, cost - cost(p)):\n",
                built.parameters[j].name.c_str());
    std::vector<double> d(scan), c(scan);
    for (int i = 0; i < scan; ++i) {
      d[i] = -span + 2 * span * i / (scan - 1);
      Eigen::VectorXd q = p;
      q[j] *= 1 + d[i];
      std::vector<Trajectory> tmp;
      c[i] = 0.5 * probe->Residuals(q, &tmp).squaredNorm();
      std::printf("    %+.4e %.10g %+.4e\n", d[i], c[i], c[i] - 0.5 * r0.squaredNorm());
    }
    // roughness: second differences against the mean curvature
    double worst = 0, mean = 0;
    for (int i = 1; i + 1 < scan; ++i) {
      const double dd = c[i + 1] - 2 * c[i] + c[i - 1];
      worst = std::max(worst, std::abs(dd));
      mean += dd / (scan - 2);
    }
    std::printf("    second differences: mean %.4g, largest |.| %.4g\n", mean, worst);
  }
}

int Main(int argc, char** argv) {
  CLI::App app{"probe a contact-rich experiment: cost cuts and Jacobians"};
  Args a;
  AddOptions(&app, &a);
  CLI11_PARSE(app, argc, argv);

  const io::ExperimentConfig cfg = io::LoadExperiment(a.exp_path);
  for (const io::DataFile& d : cfg.data) {
    if (a.write_log && !std::filesystem::exists(d.path)) {
      std::filesystem::create_directories(std::filesystem::path(d.path).parent_path());
      io::WriteLog(d.path, sim::SimulateExperiment(cfg));
      std::printf("wrote %s (simulated from the truth)\n", d.path.c_str());
    }
  }
  run::BuiltProblem built = run::BuildProblem(cfg, 1);
  if (built.models.size() != 1) throw std::invalid_argument("one model only");
  mjModel& m = *built.models[0];
  ApplySolverOptions(a, &m);
  SimulatorOptions so;
  so.threads = 2;
  so.solver_tolerance = a.tolerance;
  so.fixed_solver_iterations = a.fixed;
  Probe probe(built, m, so, a.segments);

  const Eigen::VectorXd p = ThePoint(built, cfg, a.at);
  const int np = static_cast<int>(p.size());
  std::vector<Trajectory> nominal;
  const Eigen::VectorXd r0 = probe.Residuals(p, &nominal);
  std::printf("%s at", a.exp_path.c_str());
  for (int j = 0; j < np; ++j) std::printf(" %s=%.8g", built.parameters[j].name.c_str(), p[j]);
  std::printf("\n  cost %.10g, sum(r^2)/m %.6g (m = %lld)\n", 0.5 * r0.squaredNorm(),
              r0.squaredNorm() / static_cast<double>(r0.size()), static_cast<long long>(r0.size()));
  PrintRolloutStats(nominal);

  if (a.jacobians) CompareJacobians(&probe, built, p, r0, &nominal);
  if (a.line > 1) CostLine(&probe, built, cfg, a.line, a.segments);
  CostCuts(&probe, built, p, r0, a.scan, a.span);
  return 0;
}

}  // namespace
}  // namespace mjsysid

int main(int argc, char** argv) {
  try {
    return mjsysid::Main(argc, argv);
  } catch (const std::exception& e) {
    std::fprintf(stderr, "bench_contact_probe: %s\n", e.what());
    return 2;
  }
}
