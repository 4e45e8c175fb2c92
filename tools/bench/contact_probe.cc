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
// MuJoCo options of the model can be changed for the probe: --tolerance (the solver tolerance the
// core uses, default 1e-10), --fixed-iterations, --iterations, --noslip, --elliptic, --integrator.
#include <mujoco/mujoco.h>

#include <CLI/CLI.hpp>
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <exception>
#include <sstream>
#include <string>
#include <vector>

#include "core/mujoco_env.h"
#include "core/simulator.h"
#include "sysid/io/experiment.h"
#include "sysid/run/fit_experiment.h"

namespace mjsysid {
namespace {

// one fitted sensor column of one sequence: where it sits in sensordata and its weight
struct Column {
  int col = 0;
  double weight = 1;
};

// the fit's residuals (weighted, no robust loss) of every sequence at given parameter values
class Probe {
 public:
  Probe(const run::BuiltProblem& built, const mjModel& m, const SimulatorOptions& so)
      : sim_(m, Specs(built), so) {
    for (const FitSequence& s : built.sequences) {
      inputs_.push_back(SequenceInput{s.x0, s.ctrl});
      measured_.push_back(s.measured);
      std::vector<Column> cols;
      for (const std::string& name : s.sensors) {
        const int id = mj_name2id(&m, mjOBJ_SENSOR, name.c_str());
        const auto w = built.options.sensor_weights.find(name);
        const double weight = w != built.options.sensor_weights.end() ? w->second : 1.0;
        for (int i = 0; i < m.sensor_dim[id]; ++i) cols.push_back({m.sensor_adr[id] + i, weight});
      }
      columns_.push_back(cols);
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

int Main(int argc, char** argv) {
  CLI::App app{"probe a contact-rich experiment: cost cuts and Jacobians"};
  std::string exp_path, at = "truth";
  bool jacobians = false, fixed = false, elliptic = false;
  int scan = 0, iterations = -1, noslip = -1;
  double span = 1e-3, tolerance = 1e-10;
  std::string integrator;
  app.add_option("experiment", exp_path, "EXP.yaml")->required();
  app.add_option("--at", at, "truth | start | comma-separated values");
  app.add_flag("--jacobians", jacobians, "compare the core's Jacobians with central differences");
  app.add_option("--scan", scan, "points per parameter of a 1-D cost cut (0: none)");
  app.add_option("--span", span, "relative half-width of the cut");
  app.add_option("--tolerance", tolerance, "the core's solver tolerance (min with the model's)");
  app.add_flag("--fixed-iterations", fixed, "tolerance 0: opt.iterations every step");
  app.add_option("--iterations", iterations, "opt.iterations");
  app.add_option("--noslip", noslip, "opt.noslip_iterations");
  app.add_flag("--elliptic", elliptic, "elliptic friction cones");
  app.add_option("--integrator", integrator, "euler | implicitfast | rk4 | implicit");
  CLI11_PARSE(app, argc, argv);

  const io::ExperimentConfig cfg = io::LoadExperiment(exp_path);
  run::BuiltProblem built = run::BuildProblem(cfg, 1);
  if (built.models.size() != 1) throw std::invalid_argument("one model only");
  mjModel& m = *built.models[0];
  if (iterations > 0) m.opt.iterations = iterations;
  if (noslip >= 0) m.opt.noslip_iterations = noslip;
  if (elliptic) m.opt.cone = mjCONE_ELLIPTIC;
  if (integrator == "euler") m.opt.integrator = mjINT_EULER;
  if (integrator == "implicitfast") m.opt.integrator = mjINT_IMPLICITFAST;
  if (integrator == "implicit") m.opt.integrator = mjINT_IMPLICIT;
  if (integrator == "rk4") m.opt.integrator = mjINT_RK4;
  SimulatorOptions so;
  so.threads = 2;
  so.solver_tolerance = tolerance;
  so.fixed_solver_iterations = fixed;
  Probe probe(built, m, so);

  // the point: the truth, the start, or given values
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

  std::vector<Trajectory> nominal;
  const Eigen::VectorXd r0 = probe.Residuals(p, &nominal);
  std::printf("%s at", exp_path.c_str());
  for (int j = 0; j < np; ++j) std::printf(" %s=%.8g", built.parameters[j].name.c_str(), p[j]);
  std::printf("\n  cost %.10g, sum(r^2)/m %.6g (m = %lld)\n", 0.5 * r0.squaredNorm(),
              r0.squaredNorm() / static_cast<double>(r0.size()), static_cast<long long>(r0.size()));
  PrintRolloutStats(nominal);

  if (jacobians) {
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
        J.col(j) = (probe.Residuals(pp, &tmp) - probe.Residuals(pm, &tmp)) / (2 * h * p[j]);
      }
      fd.push_back(J);
    }
    probe.Residuals(p, &nominal);
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
      const Eigen::MatrixXd J = probe.ResidualJacobian(nominal, jo, &kinks, &warnings);
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

  // 1-D cuts of the cost through p
  for (int j = 0; j < np && scan > 1; ++j) {
    std::printf("  cut along %s (relative offset d, cost, cost - cost(p)):\n",
                built.parameters[j].name.c_str());
    std::vector<double> d(scan), c(scan);
    for (int i = 0; i < scan; ++i) {
      d[i] = -span + 2 * span * i / (scan - 1);
      Eigen::VectorXd q = p;
      q[j] *= 1 + d[i];
      std::vector<Trajectory> tmp;
      c[i] = 0.5 * probe.Residuals(q, &tmp).squaredNorm();
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
