#include "sysid/data/equation_error.h"

#include <gtest/gtest.h>
#include <unistd.h>

#include <Eigen/Dense>
#include <algorithm>
#include <atomic>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <optional>
#include <random>
#include <regex>
#include <sstream>
#include <string>
#include <vector>

#include "core/mujoco_env.h"
#include "core/text.h"
#include "sysid/io/experiment.h"
#include "sysid/io/log.h"
#include "sysid/run/fit_experiment.h"
#include "sysid/run/resume.h"
#include "sysid/sim/simulate.h"
#include "tests/experiment_log.h"
#include "tests/file_util.h"
#include "tests/fit_test_util.h"

namespace mjsysid {
namespace {

namespace fs = std::filesystem;

const std::string kExperiments = MJSYSID_EXPERIMENTS_DIR;
const std::string kModels = MJSYSID_MODELS_DIR;

// experiments/pendulum.yaml written to dir with every `initial:` replaced by `auto` (and the
// model path made absolute), its log simulated as shipped next to it
std::string AutoPendulum(const fs::path& dir) {
  std::ifstream in(kExperiments + "/pendulum.yaml");
  std::stringstream text;
  text << in.rdbuf();
  std::string yaml =
      std::regex_replace(text.str(), std::regex("initial: [0-9.]+"), "initial: auto");
  yaml = std::regex_replace(yaml, std::regex("model: \\.\\./models/"), "model: " + kModels + "/");
  yaml = std::regex_replace(yaml, std::regex("data: logs/pendulum.h5"), "data: log.h5");
  const std::string path = (dir / "pendulum_auto.yaml").string();
  std::ofstream(path) << yaml;
  io::ExperimentConfig cfg = io::LoadExperiment(kExperiments + "/pendulum.yaml");
  io::WriteLog((dir / "log.h5").string(), sim::SimulateExperiment(cfg, sim::SimulateSettings{}));
  return path;
}

// experiments/pendulum.yaml (truth damping 0.08, frictionloss 0.03, bob_mass 1.2; 3 x 2000
// samples, noise 0.001 rad and 0.01 rad/s; the log holds qpos and qvel) with `initial: auto` for
// every parameter: the equation-error start lands within 15 % of the truth (measured: 0.0800,
// 0.0300, 1.200), the fit from there converges to the estimate of the shipped start (0.2, 0.01,
// 0.8) to 1e-6 relative and takes fewer LM iterations (measured 2 against 5)
TEST(EquationErrorTest, PendulumFromAutoRecoversWithFewerIterations) {
  InstallMujocoHandlers();
  const fs::path dir = fs::temp_directory_path() / ("equation_error_" + std::to_string(getpid()));
  fs::remove_all(dir);
  fs::create_directories(dir);
  const io::ExperimentConfig auto_cfg = io::LoadExperiment(AutoPendulum(dir));
  for (const io::ParameterSpec& p : auto_cfg.parameters) {
    EXPECT_TRUE(p.initial_auto) << p.name;
    EXPECT_TRUE(std::isnan(p.initial)) << p.name;
  }
  io::ExperimentConfig given_cfg = io::LoadExperiment(kExperiments + "/pendulum.yaml");
  given_cfg.data = auto_cfg.data;
  auto fit = [](const io::ExperimentConfig& cfg) {
    run::BuiltProblem b = run::BuildProblem(cfg, 1);
    FitOptions o = b.options;
    o.verbose = false;
    // Ceres' tolerances alone: the same minimum to 1e-6 relative is tighter than the statistical
    // stop (sysid/solve/gn_convergence.h, 3 % of a standard error)
    o.gauss_newton_stop = 0;
    return b.problem->Fit(o);
  };
  const FitResult from_auto = fit(auto_cfg), from_given = fit(given_cfg);
  ASSERT_TRUE(from_auto.converged);
  ASSERT_TRUE(from_given.converged);
  std::printf("iterations: auto %d, given %d\n", from_auto.iterations, from_given.iterations);
  EXPECT_LT(from_auto.iterations, from_given.iterations);
  bool noted = false;
  for (const std::string& w : from_auto.warnings) {
    std::printf("%s\n", w.c_str());
    noted = noted || w.find("equation-error start from") != std::string::npos;
  }
  EXPECT_TRUE(noted);
  for (const auto& [name, truth] : std::vector<std::pair<std::string, double>>{
           {"damping", 0.08}, {"frictionloss", 0.03}, {"bob_mass", 1.2}}) {
    const ParameterEstimate& a = test::Estimate(from_auto, name);
    const ParameterEstimate& g = test::Estimate(from_given, name);
    EXPECT_NEAR(a.initial, truth, 0.15 * truth) << name;
    EXPECT_NEAR(a.value, g.value, 1e-6 * std::abs(g.value)) << name;
  }
  fs::remove_all(dir);
}

// without logged qpos/qvel nothing is solved and the note says why; a kind that does not enter
// the inverse dynamics linearly (geom friction) is not solved either, nor anything where the
// logged motion has contacts
TEST(EquationErrorTest, NothingSolvedWithoutStatesOrForNonlinearKinds) {
  InstallMujocoHandlers();
  ModelPtr m = LoadModel(kModels + "/pendulum.xml");
  FitParameter damping("damping", ParameterSpec{"joint_damping", "hinge", "", 0, ""}, 0.2);
  FitSequence s;
  s.model = "pendulum";
  s.x0.qpos = Eigen::VectorXd::Zero(m->nq);
  s.x0.qvel = Eigen::VectorXd::Zero(m->nv);
  s.ctrl = RowMatrix::Zero(100, m->nu);
  s.measured = RowMatrix::Zero(100, m->nsensordata);
  const EquationErrorStart none = SolveEquationError(*m, {damping}, {0}, {&s});
  EXPECT_FALSE(none.solved[0]);
  EXPECT_EQ(none.values[0], 0.2);
  EXPECT_NE(none.note.find("no qpos and qvel"), std::string::npos) << none.note;
  ModelPtr box = LoadModel(kModels + "/box_floor.xml");
  FitParameter friction("friction", ParameterSpec{"geom_friction", "box", "", 0, ""}, 0.5);
  const EquationErrorStart nonlinear = SolveEquationError(*box, {friction}, {0}, {});
  EXPECT_FALSE(nonlinear.solved[0]);
  EXPECT_NE(nonlinear.note.find("linearly"), std::string::npos) << nonlinear.note;
  // the box resting on the floor (qpos0: centre 0.1 m up, half size 0.1 m; at rest): contacts in
  // every sample, so its mass is not solved
  FitParameter mass("mass", ParameterSpec{"body_mass", "box", "", 0, ""}, 1.5);
  FitSequence rest;
  rest.model = "box_floor";
  rest.x0.qpos = Eigen::Map<const Eigen::VectorXd>(box->qpos0, box->nq);
  rest.x0.qvel = Eigen::VectorXd::Zero(box->nv);
  rest.ctrl = RowMatrix::Zero(40, box->nu);
  rest.measured = RowMatrix::Zero(40, box->nsensordata);
  rest.qpos = RowMatrix(40, box->nq);
  for (int k = 0; k < 40; ++k) rest.qpos.row(k) = rest.x0.qpos.transpose();
  rest.qvel = RowMatrix::Zero(40, box->nv);
  const EquationErrorStart contact = SolveEquationError(*box, {mass}, {0}, {&rest});
  EXPECT_FALSE(contact.solved[0]);
  EXPECT_EQ(contact.values[0], 1.5);
  EXPECT_NE(contact.note.find("contacts (30 of 30 samples)"), std::string::npos) << contact.note;
  // 600 samples at rest on 1 and 2 threads (two chunks of about 300 steps): every window in
  // contact, no column, the same forces bit for bit
  rest.ctrl = RowMatrix::Zero(600, box->nu);
  rest.measured = RowMatrix::Zero(600, box->nsensordata);
  rest.qpos = rest.x0.qpos.transpose().replicate(600, 1);
  rest.qvel = RowMatrix::Zero(600, box->nv);
  std::vector<EquationErrorSystem> at;
  for (int threads : {1, 2}) {
    at.push_back(EquationErrorRegressor(*box, {mass}, {0}, {&rest}, RegressorColumns::kFastest, 5,
                                        4000, threads));
    EXPECT_EQ(at.back().samples, 590) << threads;
    EXPECT_EQ(at.back().contacts, 590) << threads;
    EXPECT_TRUE(at.back().A.isZero(0)) << threads;
  }
  EXPECT_TRUE(at[0].e0 == at[1].e0);
}

// `initial: auto` before and after its start is solved (the pendulum's equation-error start,
// within 15 % of the truth 0.08, 0.03, 1.2): "at the initial values" reads `damping = auto` while
// unsolved, the solved values once CheckJacobians (like Fit) has solved them, and the Jacobian
// check runs there (core vs Ceres within 1e-4; measured 9.3e-7; it failed on the NaN start before)
TEST(EquationErrorTest, AutoStartsReadAutoUntilSolvedThenTheirValues) {
  InstallMujocoHandlers();
  const fs::path dir = test::FreshTempDir("equation_error_at");
  const io::ExperimentConfig cfg = io::LoadExperiment(AutoPendulum(dir));
  const std::string unsolved = "damping = auto, frictionloss = auto, bob_mass = auto";
  EXPECT_NE(run::AtInitialValues(cfg).find(unsolved), std::string::npos)
      << run::AtInitialValues(cfg);
  run::BuiltProblem b = run::BuildProblem(cfg, 1);
  EXPECT_NE(run::AtInitialValues(cfg, b.problem.get()).find(unsolved), std::string::npos);
  const JacobianCheck check = b.problem->CheckJacobians(b.options);
  EXPECT_LT(check.worst_relative_error, 1e-4);
  const std::string at = run::AtInitialValues(cfg, b.problem.get());
  EXPECT_EQ(at.find("= auto"), std::string::npos) << at;
  const double truth[3] = {0.08, 0.03, 1.2};
  ASSERT_EQ(b.problem->parameters().size(), 3u);
  for (int i = 0; i < 3; ++i) {
    const FitParameter& p = b.problem->parameters()[i];
    EXPECT_FALSE(p.initial_auto) << p.name;
    EXPECT_NEAR(p.initial, truth[i], 0.15 * truth[i]) << p.name;
    EXPECT_NE(at.find(p.name + " = " + FormatDigits(p.initial, 6)), std::string::npos) << at;
  }
  fs::remove_all(dir);
}

// a fit from `initial: auto` checkpoints the solved start values (NaN before), the ones its
// result reports; resumed from the checkpoint, the experiment starts at the checkpoint's values
// (ResumedConfig), not at a new equation-error start
TEST(EquationErrorTest, AutoStartsInCheckpointsAndResumedConfig) {
  InstallMujocoHandlers();
  const fs::path dir = test::FreshTempDir("equation_error_cp");
  const io::ExperimentConfig cfg = io::LoadExperiment(AutoPendulum(dir));
  run::FitRunOptions o;
  o.out_dir = (dir / "out").string();
  o.threads = 1;
  o.verbose = false;
  std::atomic<bool> stop{false};
  o.interrupt = &stop;
  std::optional<io::FitResultFile> cp;
  o.on_iteration = [&](const IterationInfo& it) {
    if (it.iteration != 1) return;
    cp = run::FindCheckpoint(o.out_dir);  // written after every good iteration
    stop = true;
  };
  const run::FitRunOutcome first = run::RunFit(cfg, o);
  EXPECT_TRUE(first.file.interrupted);
  ASSERT_TRUE(cp.has_value());
  ASSERT_EQ(cp->parameters.size(), 3u);
  ASSERT_EQ(first.file.parameters.size(), 3u);
  for (int i = 0; i < 3; ++i) {
    const ParameterEstimate& e = cp->parameters[i];
    std::printf("[ measured ] checkpoint %s initial %.9g value %.9g\n", e.name.c_str(), e.initial,
                e.value);
    EXPECT_TRUE(std::isfinite(e.initial)) << e.name;
    EXPECT_EQ(e.initial, first.file.parameters[i].initial) << e.name;
  }
  const io::ExperimentConfig resumed = run::ResumedConfig(cfg, *cp);
  for (int i = 0; i < 3; ++i) {
    EXPECT_FALSE(resumed.parameters[i].initial_auto) << resumed.parameters[i].name;
    EXPECT_EQ(resumed.parameters[i].initial, cp->parameters[i].value);
  }
  fs::remove_all(dir);
}

// the regressor's closed forms and stage skips (what the fit uses) against forward differences
// of full mj_inverse calls at every column, on the shipped arm7 (joint friction loss, six link
// masses, seven dampings, seven armatures; 3 x 2000 steps; implicitfast), cartpole (pole mass,
// cart damping, slide friction loss; 3 x 2000; Euler) and spring_mass (damping, stiffness: a
// stage skip, and the motor's gain instead of the mass: actuation only, the solution scaled by
// the model's mass over the true one; Euler) and double_pendulum (two link masses with their
// inertias scaled along; Euler) experiments with
// their simulated logs, once with the logged states (the integrator's own: the one-step form)
// and once with noise added to them (0.001 in qpos, 0.01 in qvel: smoothed states,
// sysid/data/state_smoothing.h): e(p0)
// the same to the bit; every column within 1e-9 of its norm on the rows of dofs without friction
// loss (measured
// <= 8e-11, the forward difference's rounding) and within 5e-3 on all rows (measured 2.3e-3 on
// arm7: the closed form is the friction row's force in its linear zones; in the quadratic zone
// its force -D jar also moves with the other parameters, through the discrete acceleration and
// through the regularisation mj_setConst derives from the masses and armatures); both solved
// starts within 1e-3 relative of each other and, from the exact states, of the truth (the
// simulated noise is on the sensors; measured in [ measured ]); the fast system the same bit for
// bit with its samples on 2 and 3 threads
TEST(EquationErrorTest, ClosedFormColumnsEqualForwardDifferences) {
  InstallMujocoHandlers();
  for (const std::string name : {"arm7", "cartpole", "spring_mass", "double_pendulum"}) {
    const io::ExperimentConfig cfg =
        test::ShippedExperimentWithLog(name + ".yaml", 3, 2000, "equation_error_cf_" + name);
    for (const bool noisy : {false, true}) {
      run::BuiltProblem b = run::BuildProblem(cfg, 1);
      ASSERT_EQ(b.models.size(), 1u);
      if (name == "spring_mass") {
        // the gain instead of the mass (all four scale together)
        ASSERT_EQ(b.parameters[0].target.kind, "body_mass");
        b.parameters.erase(b.parameters.begin());
        b.parameters.emplace_back("gain", ParameterSpec{"actuator_gain", "force", "", 0, ""}, 1.0);
      }
      // noisy: the logged states with Gaussian noise (0.001 in qpos, 0.01 in qvel; seed 1)
      std::mt19937 rng(1);
      std::normal_distribution<double> normal;
      std::vector<const FitSequence*> sequences;
      for (FitSequence& s : b.sequences) {
        for (Eigen::Index i = 0; noisy && i < s.qpos.size(); ++i)
          s.qpos.data()[i] += 1e-3 * normal(rng);
        for (Eigen::Index i = 0; noisy && i < s.qvel.size(); ++i)
          s.qvel.data()[i] += 1e-2 * normal(rng);
        sequences.push_back(&s);
      }
      std::vector<int> cols;
      for (size_t g = 0; g < b.parameters.size(); ++g) cols.push_back(static_cast<int>(g));
      const EquationErrorSystem fast = EquationErrorRegressor(
          *b.models[0], b.parameters, cols, sequences, RegressorColumns::kFastest);
      const EquationErrorSystem fd = EquationErrorRegressor(
          *b.models[0], b.parameters, cols, sequences, RegressorColumns::kForwardDifference);
      ASSERT_TRUE(fast.note.empty()) << fast.note;
      // the samples in 2 and 3 chunks on as many threads: the same system bit for bit
      for (int threads : {2, 3}) {
        const EquationErrorSystem par =
            EquationErrorRegressor(*b.models[0], b.parameters, cols, sequences,
                                   RegressorColumns::kFastest, 5, 4000, threads);
        EXPECT_TRUE(par.A == fast.A && par.e0 == fast.e0) << name << " at " << threads;
      }
      EXPECT_EQ(fast.discrete, !noisy) << name;
      EXPECT_EQ(fd.discrete, !noisy) << name;
      EXPECT_EQ(fast.contacts, 0);
      // the integrator's steps: windows of 10 around every sample 5 .. 1994; smoothed: every sample
      // but the first and last two of each sequence (their differences need neighbours)
      EXPECT_EQ(fast.samples, noisy ? 3 * 1996 : 5970);
      ASSERT_EQ(fast.A.rows(), fd.A.rows());
      EXPECT_TRUE(fast.e0 == fd.e0) << name;
      double worst = 0, worst_off = 0;
      for (size_t c = 0; c < cols.size(); ++c) {
        const std::string& kind = b.parameters[c].target.kind;
        EXPECT_EQ(fast.closed_form[c], kind != "joint_stiffness" && kind != "actuator_gain")
            << name << " " << b.parameters[c].name;
        EXPECT_FALSE(fd.closed_form[c]);
        const double norm = fd.A.col(c).norm();
        ASSERT_GT(norm, 0) << b.parameters[c].name;
        const double error = (fast.A.col(c) - fd.A.col(c)).norm() / norm;
        worst = std::max(worst, error);
        EXPECT_LT(error, 5e-3) << name << " " << b.parameters[c].name;
        double off = 0;  // the rows of dofs without friction loss
        for (int r = 0; r < fast.A.rows(); ++r) {
          if (b.models[0]->dof_frictionloss[r % b.models[0]->nv] > 0) continue;
          off += std::pow(fast.A(r, c) - fd.A(r, c), 2);
        }
        worst_off = std::max(worst_off, std::sqrt(off) / norm);
        EXPECT_LT(std::sqrt(off), 1e-9 * norm) << name << " " << b.parameters[c].name;
      }
      const Eigen::VectorXd x_fast = fast.A.colPivHouseholderQr().solve(-fast.e0);
      const Eigen::VectorXd x_fd = fd.A.colPivHouseholderQr().solve(-fd.e0);
      double worst_truth = 0, worst_fd = 0;
      // spring_mass: the mass stays at the model's value, so the solution is the truth scaled by it
      double scale = 1;
      for (const io::NamedValue& t : cfg.simulate.truth) {
        if (name == "spring_mass" && t.name == "mass") scale = b.models[0]->body_mass[1] / t.value;
      }
      for (size_t c = 0; c < cols.size(); ++c) {
        double truth = 1.0;  // the gain's: the model's
        for (const io::NamedValue& t : cfg.simulate.truth) {
          if (t.name == b.parameters[c].name) truth = t.value;
        }
        truth *= scale;
        const double start = fast.p0[c] + x_fast[c], start_fd = fd.p0[c] + x_fd[c];
        worst_truth = std::max(worst_truth, std::abs(start / truth - 1));
        worst_fd = std::max(worst_fd, std::abs(start / start_fd - 1));
        if (!noisy) {
          EXPECT_NEAR(start, truth, 1e-3 * truth) << name << " " << b.parameters[c].name;
        }
        EXPECT_NEAR(start, start_fd, 1e-3 * std::abs(start_fd)) << b.parameters[c].name;
      }
      std::printf(
          "[ measured ] %s%s: worst column error %.3g (%.3g without friction-loss rows); start vs "
          "truth %.3g, vs forward differences %.3g (relative)\n",
          name.c_str(), noisy ? " (noisy states)" : "", worst, worst_off, worst_truth, worst_fd);
    }
  }
}

// The equation-error start (states smoothed: sysid/data/state_smoothing.h) on the shipped
// experiments' simulated logs (3 x 2000 samples) with
// Gaussian noise of 1 % of each channel's standard deviation added to qpos and qvel (seed 5),
// and from the positions alone quantized to 2 pi / 2^14 (a 14-bit encoder). The largest
// relative error from the truth over the parameters is within each case's tolerance, each above
// the value measured at this seed (printed in [ measured ]). The goal is 5 %: with noise,
// spring-mass, double pendulum and cart-pole meet it here; pendulum (its friction loss) and arm7
// do not, and neither do the pendulum's encoders (docs/numerics.md, "The equation-error start on
// noisy logs": both times a friction loss, a small force whose estimate the acceleration noise
// swamps, and the friction rows' zones near zero velocity). Their tolerances guard
// today's level, far below the 6-81 % of the unsmoothed start with noise (encoders: no start).
// arm5 (five armatures of a planar arm) is a case the smoothing was never tuned on, added after
// it was built: the goal's 5 % with noise (measured 0.44 %), 10 % from encoders (5.2 %).
TEST(EquationErrorTest, StartOnNoisyAndEncoderLogs) {
  InstallMujocoHandlers();
  struct Case {
    const char* name;
    bool encoder;
    double tolerance;
  };
  for (const Case& c : {Case{"spring_mass", false, 0.05}, Case{"pendulum", false, 0.12},
                        Case{"double_pendulum", false, 0.05}, Case{"cartpole", false, 0.05},
                        Case{"arm7", false, 0.12}, Case{"spring_mass", true, 0.02},
                        Case{"double_pendulum", true, 0.06}, Case{"pendulum", true, 0.20},
                        Case{"arm5", false, 0.05}, Case{"arm5", true, 0.10}}) {
    const std::string name = c.name;
    const io::ExperimentConfig cfg = test::ShippedExperimentWithLog(
        name + ".yaml", 3, 2000, "equation_error_smoothed_" + name + (c.encoder ? "_enc" : ""));
    run::BuiltProblem b = run::BuildProblem(cfg, 1);
    test::NormalNoise noise(5);
    const double quantum = 2 * M_PI / 16384;
    std::vector<const FitSequence*> sequences;
    for (FitSequence& s : b.sequences) {
      if (c.encoder) {
        s.qpos = (s.qpos / quantum).array().round().matrix() * quantum;
        s.qvel.resize(0, s.qvel.cols());
      } else {
        for (RowMatrix* x : {&s.qpos, &s.qvel}) test::AddRelativeNoise(0.01, &noise, x);
      }
      sequences.push_back(&s);
    }
    std::vector<int> which;
    for (size_t g = 0; g < b.parameters.size(); ++g) which.push_back(static_cast<int>(g));
    const EquationErrorStart start =
        SolveEquationError(*b.models[0], b.parameters, which, sequences);
    double worst = 0;
    for (size_t g = 0; g < b.parameters.size(); ++g) {
      ASSERT_TRUE(start.solved[g]) << name << ": " << start.note;
      for (const io::NamedValue& t : cfg.simulate.truth) {
        if (t.name == b.parameters[g].name) {
          worst = std::max(worst, std::abs(start.values[g] / t.value - 1));
        }
      }
    }
    std::printf("[ measured ] %s%s: largest error %.2f %% (%s)\n", c.name,
                c.encoder ? " (14-bit encoders only)" : " (1 % noise)", 100 * worst,
                start.note.c_str());
    EXPECT_LT(worst, c.tolerance) << name;
  }
}

}  // namespace
}  // namespace mjsysid
