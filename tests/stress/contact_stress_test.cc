// Stress: contacts from stiff to soft, solimp extremes, tiny and large timesteps, on a box
// sliding on a floor (box_slide.xml's scene, two slide joints, contact at every step).
// For each case: Jacobian accuracy of the directional and matrix modes against central
// whole-rollout differences over 1 s (settled on the floor first), and a short noise-free fit of
// the sliding friction and the mass (truth 0.5, 2.0; start 0.3, 3.0) over 2 x 1.5 s of pushes.
// Contact Jacobians and fits are inherently limited (docs/numerics.md: contact flicker makes the
// cost rugged at the 1% level): each case states the error measured on this build, and the test
// bounds sit above it with headroom; docs/stress.md records the numbers.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <filesystem>
#include <string>
#include <vector>

#include "sysid/io/log.h"
#include "sysid/run/fit_experiment.h"
#include "sysid/sim/simulate.h"
#include "tests/file_util.h"
#include "tests/stress/stress_util.h"

namespace mjsysid {
namespace {

namespace fs = std::filesystem;
using stress::ColumnScaledError;
using stress::Excitation;
using stress::Spec;

struct ContactCase {
  std::string name;
  double dt;
  std::string solref, solimp;  // geom attributes of the box
  double tol_jac_forward;      // column-scaled Jacobian error bounds (forward, central)
  double tol_jac_central;
  double tol_fit;  // relative error of mu and mass
  // false where central whole-rollout differences cross contact switches and stop being an
  // oracle (measured: column-scaled error 1.0 for every mode, also central, at solimp dmax
  // 0.9999 and at dt 1e-4): there the directional and matrix modes are checked against each
  // other (central, tol_jac_central x 100) instead
  bool oracle_ok = true;
  // false where the fit measured does not recover (dt 0.02: stalls at 40% error, cost 3.6e-2 ->
  // 3.5e-2): then only required finite and not worse than the start
  bool fit_recovers = true;
};
// gtest prints a case by name (not as bytes) in test listings and failures
void PrintTo(const ContactCase& c, std::ostream* os) { *os << c.name; }

std::string BoxXml(const ContactCase& c) {
  char buf[2048];
  std::snprintf(buf, sizeof(buf), R"(
<mujoco>
  <option timestep="%g" integrator="Euler"/>
  <worldbody>
    <geom name="floor" type="plane" size="5 5 0.1" friction="0.05 0.001 0.00001"/>
    <body name="box" pos="0 0 0.1">
      <joint name="x" type="slide" axis="1 0 0"/>
      <joint name="z" type="slide" axis="0 0 1"/>
      <geom name="box" type="box" size="0.1 0.1 0.1" mass="2.0" friction="0.5 0.005 0.0001"
            solref="%s" solimp="%s"/>
    </body>
  </worldbody>
  <actuator><motor name="push" joint="x" gear="1"/></actuator>
  <sensor>
    <jointpos name="x" joint="x"/><jointvel name="xdot" joint="x"/><jointpos name="z" joint="z"/>
  </sensor>
</mujoco>)",
                c.dt, c.solref.c_str(), c.solimp.c_str());
  return buf;
}

// settled on the floor at rest: the state after 0.5 s at zero push
InitialState Settled(const mjModel& m) {
  Simulator sim(m, {});
  const int n = static_cast<int>(0.5 / m.opt.timestep);
  const Trajectory rest = sim.Rollout(SequenceInput{InitialState(), RowMatrix::Zero(n, 1)});
  InitialState x0;
  x0.qpos = rest.states.row(n).head(m.nq);
  x0.qvel = rest.states.row(n).segment(m.nq, m.nv);
  return x0;
}

const char* kDefaultImp = "0.9 0.95 0.001 0.5 2";

// bounds: set from the measured values (docs/stress.md) with >= 3x headroom
const std::vector<ContactCase>& Cases() {
  static const std::vector<ContactCase> cases = {
      {"default", 0.002, "0.02 1", kDefaultImp, 1e-3, 2e-5, 3e-2},
      // stiffest MuJoCo allows without clamping: timeconst 2*dt (solref 0.002 needs dt 0.001)
      {"stiff", 0.001, "0.002 1", kDefaultImp, 1e-3, 2e-5, 3e-2},
      {"soft", 0.002, "0.1 1", kDefaultImp, 1e-3, 2e-5, 3e-2},
      {"very_soft", 0.002, "0.3 1", kDefaultImp, 1e-3, 2e-5, 3e-2},
      {"overdamped", 0.002, "0.02 4", kDefaultImp, 1e-3, 2e-5, 1e-1},
      {"solimp_low", 0.002, "0.02 1", "0.0001 0.0001 0.001 0.5 2", 1e-3, 1e-4, 3e-2},
      {"solimp_high", 0.002, "0.02 1", "0.9999 0.9999 0.001 0.5 2", 1e-3, 2e-5, 3e-2, false},
      {"solimp_wide", 0.002, "0.02 1", "0.0001 0.9999 0.1 0.5 6", 1e-3, 2e-5, 3e-2},
      {"dt_tiny", 1e-4, "0.02 1", kDefaultImp, 1e-3, 2e-5, 3e-2, false},
      {"dt_large", 0.02, "0.04 1", kDefaultImp, 1e-3, 2e-5, 3e-2, true, false},
      {"dt_huge", 0.05, "0.1 1", kDefaultImp, 1e-3, 2e-5, 3e-2},
  };
  return cases;
}

class ContactStressTest : public ::testing::TestWithParam<ContactCase> {};

TEST_P(ContactStressTest, JacobianAccuracy) {
  const ContactCase& c = GetParam();
  ModelPtr m = LoadModelFromString(BoxXml(c));
  SimulatorOptions so;
  so.threads = 2;
  Simulator sim(*m, {Spec("geom_friction", "box", 0), Spec("body_mass", "box")}, so);
  const int T = std::max(20, static_cast<int>((stress::LongMode() ? 5.0 : 1.0) / c.dt));
  SequenceInput seq{Settled(*m), Excitation(*m, T, 14.0, 30, 3.0)};
  const Trajectory nominal = sim.Rollout(seq);
  JacobianOptions ref_opt;
  ref_opt.mode = JacobianMode::kWholeRollout;
  ref_opt.central = true;
  const Sensitivity ref = sim.Jacobians(seq, nominal, ref_opt);
  int contact_steps = 0;
  for (int k = 0; k < T; ++k) contact_steps += nominal.ncon[k] > 0;
  RowMatrix dir_central;
  for (JacobianMode mode : {JacobianMode::kDirectional, JacobianMode::kMatrix}) {
    for (bool central : {false, true}) {
      JacobianOptions opt;
      opt.mode = mode;
      opt.central = central;
      const Sensitivity s = sim.Jacobians(seq, nominal, opt);
      if (central && mode == JacobianMode::kDirectional) dir_central = s.DxDp;
      if (central && mode == JacobianMode::kMatrix) {
        const double cross = ColumnScaledError(s.DxDp, dir_central);
        std::printf("[ stress ] contact %-12s matrix/central vs directional/central err=%.2e\n",
                    c.name.c_str(), cross);
        if (!c.oracle_ok) {
          EXPECT_LE(cross, 100 * c.tol_jac_central) << c.name;
        }
      }
      const double err =
          std::max(ColumnScaledError(s.DyDp, ref.DyDp), ColumnScaledError(s.DxDp, ref.DxDp));
      const double tol = central ? c.tol_jac_central : c.tol_jac_forward;
      std::printf(
          "[ stress ] contact %-12s dt=%-7g T=%-5d contact %3d%% %-19s err=%.2e kinks=%d "
          "tol=%.0e\n",
          c.name.c_str(), c.dt, T, 100 * contact_steps / T,
          (std::string(JacobianModeName(mode)) + (central ? "/central" : "/forward")).c_str(), err,
          s.kinks, tol);
      EXPECT_TRUE(s.DyDp.allFinite() && s.DxDp.allFinite());
      if (c.oracle_ok) {
        EXPECT_LE(err, tol) << c.name << " " << JacobianModeName(mode)
                            << (central ? " central" : " forward");
      }
    }
  }
}

TEST_P(ContactStressTest, ShortFit) {
  const ContactCase& c = GetParam();
  ModelPtr m = LoadModelFromString(BoxXml(c));
  const std::vector<stress::Truth> truth = {{"mu", Spec("geom_friction", "box", 0), 0.5},
                                            {"mass", Spec("body_mass", "box"), 2.0}};
  const InitialState x0 = Settled(*m);
  Problem problem;
  problem.AddModel("box", *m);
  problem.AddParameter(FitParameter("mu", truth[0].spec, 0.3).Bounds(0.06, 2).Log());
  problem.AddParameter(FitParameter("mass", truth[1].spec, 3.0).Bounds(0.1, 20).Log());
  // dt 1e-4: 2 x 15,000 steps per evaluation, the slowest case: long mode only
  if (c.dt < 5e-4 && !stress::LongMode()) GTEST_SKIP() << "long mode only (MJSYSID_STRESS_LONG=1)";
  const int T = static_cast<int>(1.5 / c.dt);
  for (int s = 0; s < 2; ++s) {
    const RowMatrix u = Excitation(*m, T, 14.0, 30 + s, 3.0);
    problem.AddSequence(FitSequence("seq" + std::to_string(s), "box", x0, u,
                                    stress::Measure(*m, truth, x0, u, 0, 0)));
  }
  FitOptions opt;
  opt.threads = 2;
  opt.max_iterations = 30;  // contact fits creep (rugged cost): measured errors at 30-50 agree
  const FitResult r = problem.Fit(opt);
  const double err = stress::WorstRelativeError(r, truth);
  std::printf(
      "[ stress ] contact fit %-12s dt=%-7g mu %.5f mass %.5f error %.2e, cost %.2e -> "
      "%.2e, %d iterations, %s, tol %.0e\n",
      c.name.c_str(), c.dt, stress::Estimate(r, "mu").value, stress::Estimate(r, "mass").value, err,
      r.initial_cost, r.final_cost, r.iterations, r.converged ? "converged" : "not converged",
      c.tol_fit);
  EXPECT_TRUE(stress::AllFinite(r));
  EXPECT_LE(r.final_cost, r.initial_cost) << c.name;
  if (c.fit_recovers) {
    EXPECT_LT(r.final_cost, 0.2 * r.initial_cost) << c.name;
    EXPECT_LE(err, c.tol_fit) << c.name;
  }
}

INSTANTIATE_TEST_SUITE_P(Cases, ContactStressTest, ::testing::ValuesIn(Cases()),
                         [](const auto& param_info) { return param_info.param.name; });

// The shipped box_floor experiment (a free box pushed at 25 N: it slides and hops), its log
// simulated from the truth (friction 0.6, mass 2.5) with the experiment's noise (1 mm, 0.01 m/s)
// and seed, its parameters at the truth (docs/numerics.md, "Contact: a rugged cost"):
// - the core's Jacobians are exact: directional and matrix, central, agree with whole-rollout
//   central differences at relative steps of 1e-7 (column-scaled error measured 1.0e-7 and
//   3.6e-5; bound 3e-4),
// - but the cost is not smooth at the scale of the data: whole-rollout central differences at
//   1e-4 relative cross contact events and are no derivative (measured: 318 times the largest
//   entry off; bound 0.5), and a step of 4e-5 relative in friction (0.2 of its standard error)
//   raises the cost by more than half (measured x3.9; bound x1.5).
// Then the fit (from the experiment's start 0.4, 1.5) must say so: not converged, a non-zero exit
// code, intervals not valid, and a warning that the cost is rugged at the intervals' scale.
TEST(BoxFloorContact, JacobianExactCostJumpsFitSaysSo) {
  const fs::path dir = test::FreshTempDir("contact_box_floor");
  io::ExperimentConfig cfg =
      io::LoadExperiment(std::string(MJSYSID_EXPERIMENTS_DIR) + "/box_floor.yaml");
  const std::string log = (dir / "log.h5").string();
  cfg.data = {io::DataFile{log, {}}};
  io::WriteLog(log, sim::SimulateExperiment(cfg, sim::SimulateSettings{}));
  run::BuiltProblem built = run::BuildProblem(cfg, 2);
  ASSERT_EQ(built.parameters.size(), 2u);

  // the simulator at the truth, the experiment's sequences
  std::vector<ParameterSpec> specs;
  Eigen::VectorXd truth(2);
  for (int j = 0; j < 2; ++j) {
    specs.push_back(built.parameters[j].target);
    for (const io::NamedValue& t : cfg.simulate.truth)
      if (t.name == built.parameters[j].name) truth[j] = t.value;
  }
  SimulatorOptions so;
  so.threads = 2;
  Simulator sim(*built.models[0], specs, so);
  sim.SetParameters(truth);
  std::vector<SequenceInput> in;
  for (const FitSequence& s : built.sequences) in.push_back(SequenceInput{s.x0, s.ctrl});
  std::vector<Trajectory> nominal;
  sim.Rollout(in, &nominal);

  // sensor Jacobians of one mode, all sequences stacked
  auto stacked = [&](JacobianMode mode, double relative_step) {
    JacobianOptions jo;
    jo.mode = mode;
    jo.central = true;
    jo.relative_step = relative_step;
    jo.state_jacobians = false;
    std::vector<Sensitivity> sens;
    sim.Jacobians(in, nominal, jo, &sens);
    Eigen::Index rows = 0;
    for (const Sensitivity& s : sens) rows += s.DyDp.rows();
    RowMatrix J(rows, 2);
    rows = 0;
    for (const Sensitivity& s : sens) {
      J.middleRows(rows, s.DyDp.rows()) = s.DyDp;
      rows += s.DyDp.rows();
    }
    return J;
  };
  const RowMatrix oracle = stacked(JacobianMode::kWholeRollout, 1e-7);
  const double directional = ColumnScaledError(stacked(JacobianMode::kDirectional, 1e-6), oracle);
  const double matrix = ColumnScaledError(stacked(JacobianMode::kMatrix, 1e-6), oracle);
  const double coarse = ColumnScaledError(stacked(JacobianMode::kWholeRollout, 1e-4), oracle);

  // the plain cost 0.5 |r|^2 of the fitted sensors at the truth and 4e-5 relative friction away
  auto cost = [&](const Eigen::VectorXd& p) {
    sim.SetParameters(p);
    std::vector<Trajectory> tr;
    sim.Rollout(in, &tr);
    const mjModel& m = sim.model();
    double c = 0;
    for (size_t q = 0; q < in.size(); ++q) {
      for (const std::string& name : built.sequences[q].sensors) {
        const int id = mj_name2id(&m, mjOBJ_SENSOR, name.c_str());
        const double w = built.options.sensor_weights.at(name);
        const auto cols = Eigen::seqN(m.sensor_adr[id], m.sensor_dim[id]);
        c += 0.5 * w * w *
             (tr[q].sensors(Eigen::all, cols) - built.sequences[q].measured(Eigen::all, cols))
                 .squaredNorm();
      }
    }
    return c;
  };
  const double at_truth = cost(truth);
  Eigen::VectorXd moved = truth;
  moved[0] *= 1 + 4e-5;
  const double at_moved = cost(moved);
  std::printf(
      "[ stress ] box_floor at the truth: Jacobian error directional %.2e matrix %.2e (central, "
      "vs whole rollout 1e-7); whole rollout 1e-4 vs 1e-7 %.2e; cost %.6g, friction +4e-5: %.6g\n",
      directional, matrix, coarse, at_truth, at_moved);
  EXPECT_LE(directional, 1e-4);
  EXPECT_LE(matrix, 3e-4);
  EXPECT_GE(coarse, 0.5);
  EXPECT_GE(at_moved, 1.5 * at_truth);

  // the fit says that its intervals describe nothing
  run::FitRunOptions opt;
  opt.out_dir = (dir / "out").string();
  opt.verbose = false;
  const run::FitRunOutcome out = run::RunFit(cfg, opt);
  for (const ParameterEstimate& p : out.file.parameters) {
    std::printf("[ stress ] box_floor fit: %s %s %.6g (truth %.6g, std %.3g)\n",
                out.file.status.c_str(), p.name.c_str(), p.value, p.truth.value_or(NAN),
                p.std_error);
  }
  EXPECT_NE(out.file.outcome, FitStatus::kConverged);
  EXPECT_NE(out.exit_code, 0);
  EXPECT_FALSE(out.file.intervals_valid);
  // the rugged cost is named: the interval check failed ("not smooth"), or it failed and the
  // envelope check (sysid/assess/interval_check.h) held; measured: the envelope holds at this
  // estimate with the truth 13 standard errors away (the check is local), and the chi-square test
  // says model_mismatch (the estimate does not explain the data as the truth does)
  bool said = false;
  for (const std::string& w : out.file.warnings) {
    said = said || w.find("not smooth at the scale of the intervals") != std::string::npos ||
           w.find("the cost is rugged at the scale of the intervals") != std::string::npos;
  }
  EXPECT_TRUE(said) << "no warning about the rugged cost";
  fs::remove_all(dir);
}

}  // namespace
}  // namespace mjsysid
