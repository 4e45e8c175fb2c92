// Logged states as fitted data (sysid/solve/state_residuals.h): the cost function's Jacobians
// against Ceres' numeric differentiation (a free body's quaternion, a hinge chain off the grid),
// recovery of damping and mass on a model without sensors from its states alone, and the input
// errors. Real MuJoCo throughout; each test states truth, start, noise and tolerance.
#include "sysid/solve/state_residuals.h"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <random>
#include <string>
#include <vector>

#include "core/mujoco_env.h"
#include "core/simulator.h"
#include "sysid/problem.h"
#include "tests/fit_test_util.h"
#include "tests/test_util.h"

namespace mjsysid {
namespace {

using test::Estimate;
using test::Excitation;
using test::Spec;
using test::Truth;

// a free box pushed and twisted by three motors, damped, under gravity, no contact and no sensor
const char* kFreeBody = R"(
<mujoco model="free_body">
  <option timestep="0.002" integrator="Euler"/>
  <worldbody>
    <body name="box" pos="0 0 1">
      <joint name="free" type="free" damping="0.3"/>
      <geom name="box" type="box" size="0.2 0.1 0.05" mass="1.5"/>
    </body>
  </worldbody>
  <actuator>
    <motor name="fx" joint="free" gear="1 0 0 0 0 0"/>
    <motor name="tx" joint="free" gear="0 0 0 0.2 0 0"/>
    <motor name="tz" joint="free" gear="0 0 0 0 0 0.2"/>
  </actuator>
</mujoco>)";

// The logged states of a rollout with the true values at the sample times `time` (empty: one
// sample per step, T samples), with Gaussian noise sigma_q on qpos and sigma_v on qvel (a noisy
// quaternion is renormalised by the fit)
FitSequence StateLog(const mjModel& m, const std::vector<Truth>& truth, const InitialState& x0,
                     const RowMatrix& u, int T, const Eigen::VectorXd& time, double sigma_q,
                     double sigma_v, int seed) {
  const std::unique_ptr<Simulator> simulator = test::TrueSimulator(m, truth);
  Simulator& sim = *simulator;
  const StateDims d(m);
  // at the sample times: simulate on the grid and read the states at the samples' positions
  const int steps = time.size() ? static_cast<int>(std::ceil(time[T - 1] / m.opt.timestep)) + 2 : T;
  RowMatrix ctrl(steps, m.nu);
  for (int n = 0; n < steps; ++n) ctrl.row(n) = u.row(std::min<int>(n, u.rows() - 1));
  const Trajectory tr = sim.Rollout(SequenceInput{x0, ctrl});
  FitSequence sq("seq0", "m", x0, RowMatrix(), RowMatrix(T, d.ns));
  sq.qpos.resize(T, d.nq);
  sq.qvel.resize(T, d.nv);
  std::vector<double> x(d.nphys), scratch(d.nx);
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> n01(0, 1);
  for (int k = 0; k < T; ++k) {
    StateAtPosition(m, tr.states, time.size() ? time[k] / m.opt.timestep : k, scratch.data(),
                    x.data());
    for (int i = 0; i < d.nq; ++i) sq.qpos(k, i) = x[i] + sigma_q * n01(rng);
    for (int i = 0; i < d.nv; ++i) sq.qvel(k, i) = x[d.nq + i] + sigma_v * n01(rng);
  }
  // controls at the sample times (zero-order hold of the grid's)
  sq.ctrl.resize(T, m.nu);
  for (int k = 0; k < T; ++k) {
    const int n = time.size() ? static_cast<int>(std::floor(time[k] / m.opt.timestep + 1e-9)) : k;
    sq.ctrl.row(k) = ctrl.row(n);
  }
  if (time.size()) sq.time = time;
  return sq;
}

FitStates QposQvel(double sigma_q, double sigma_v) {
  FitStates st;
  st.qpos.fit = st.qvel.fit = true;
  st.qpos.sigma = {sigma_q};
  st.qvel.sigma = {sigma_v};
  return st;
}

void PrintCheck(const JacobianCheck& check) {
  for (const auto& [name, err] : check.per_variable) {
    std::printf("[ measured ] %-28s worst relative error %.2e\n", name.c_str(), err);
  }
  std::printf("[ measured ] worst %.2e at %s\n", check.worst_relative_error,
              check.worst_where.c_str());
}

// the Jacobians of the fit of truth's damping (log, bounds 1e-3..10) and mass (bounds 0.1..10)
// from their starts to sq against ceres::GradientChecker (printed): at least `variables`
// variables checked, the worst within 1e-4 column-scaled (as the sensor check)
void ExpectDampingMassJacobians(const mjModel& m, const std::vector<Truth>& truth, double damping,
                                double mass, const FitSequence& sq, const FitOptions& opt,
                                size_t variables) {
  Problem problem;
  problem.AddModel("m", m);
  problem.AddParameter(FitParameter("damping", truth[0].spec, damping).Bounds(1e-3, 10).Log());
  problem.AddParameter(FitParameter("mass", truth[1].spec, mass).Bounds(0.1, 10));
  problem.AddSequence(sq);
  const JacobianCheck check = problem.CheckJacobians(opt);
  PrintCheck(check);
  EXPECT_GE(check.per_variable.size(), variables);
  EXPECT_LE(check.worst_relative_error, 1e-4) << check.worst_where;
}

// the free body's start: 1 m up, turned 0.6 rad about (0.6, 0, 0.8), moving and spinning
InitialState FreeBodyStart() {
  InitialState x0;
  x0.qpos.resize(7);
  x0.qpos << 0, 0, 1, std::cos(0.3), std::sin(0.3) * 0.6, 0, std::sin(0.3) * 0.8;
  x0.qvel.resize(6);
  x0.qvel << 0.2, -0.1, 0.5, 2.0, -1.0, 3.0;
  return x0;
}

// free body, qpos (position + quaternion) and qvel residuals, truth damping 0.3, mass 1.5, start
// 0.6 and 1.1 (residuals far from zero, so the orientation's Jr^-1 matters), noise-free; x_0 a
// variable (multiple shooting, 2 segments). Tolerance 1e-4 column-scaled, as the sensor check
TEST(StateResidualsTest, FreeBodyJacobiansAgreeWithCeres) {
  ModelPtr m = LoadModelFromString(kFreeBody);
  const InitialState x0 = FreeBodyStart();
  const int T = 200;
  const RowMatrix u = Excitation(*m, T, 1.0, 4);
  const std::vector<Truth> truth = {{"damping", Spec("joint_damping", "free"), 0.3},
                                    {"mass", Spec("body_mass", "box"), 1.5}};
  const FitSequence sq = StateLog(*m, truth, x0, u, T, Eigen::VectorXd(), 0, 0, 0);
  FitOptions opt;
  opt.states = QposQvel(1e-3, 1e-2);
  opt.estimate_initial_state = true;
  opt.segment_steps = 100;
  ExpectDampingMassJacobians(*m, truth, 0.6, 1.1, sq, opt, 3);
}

// free body as above logged at 3.3 ms on a 2 ms grid: an orientation between two steps is
// interpolated on SO(3) but its Jacobian rows linearly (first order in one step's rotation, here
// up to 3.2 rad/s x 2 ms); x_0 fixed. Tolerance 1e-4 column-scaled, as on the grid
TEST(StateResidualsTest, FreeBodyOffGridJacobiansAgreeWithCeres) {
  ModelPtr m = LoadModelFromString(kFreeBody);
  const InitialState x0 = FreeBodyStart();
  const int T = 120;
  const Eigen::VectorXd time = Eigen::VectorXd::LinSpaced(T, 0, (T - 1) * 0.0033);
  const RowMatrix u = Excitation(*m, 400, 1.0, 4);
  const std::vector<Truth> truth = {{"damping", Spec("joint_damping", "free"), 0.3},
                                    {"mass", Spec("body_mass", "box"), 1.5}};
  const FitSequence sq = StateLog(*m, truth, x0, u, T, time, 0, 0, 0);
  FitOptions opt;
  opt.states = QposQvel(1e-3, 1e-2);
  ExpectDampingMassJacobians(*m, truth, 0.6, 1.1, sq, opt, 2);
}

// hinge chain, qpos and qvel of both joints logged at 3.3 ms on a 2 ms grid (every sample off
// the grid: the state and its rows interpolated), truth damping 0.2, mass 1.0, start 0.5, 1.6;
// tolerance 1e-4 column-scaled
TEST(StateResidualsTest, HingeChainOffGridJacobiansAgreeWithCeres) {
  ModelPtr m = LoadModelFromString(test::kChainXml);
  InitialState x0;
  x0.qpos = Eigen::Vector2d(0.4, -0.3);
  const int T = 120;
  const Eigen::VectorXd time = Eigen::VectorXd::LinSpaced(T, 0, (T - 1) * 0.0033);
  const RowMatrix u = Excitation(*m, 400, 2.0, 5);
  const std::vector<Truth> truth = {{"damping", Spec("joint_damping", "hinge1"), 0.2},
                                    {"mass", Spec("body_mass", "link1"), 1.0}};
  const FitSequence sq = StateLog(*m, truth, x0, u, T, time, 0, 0, 0);
  FitOptions opt;
  opt.states = QposQvel(1e-3, 1e-2);
  opt.estimate_initial_state = true;
  ExpectDampingMassJacobians(*m, truth, 0.5, 1.6, sq, opt, 3);
}

// a hinge driven through a first-order filter actuator (one activation), no sensor
const char* kFiltered = R"(
<mujoco model="filtered">
  <option timestep="0.002" integrator="Euler"/>
  <worldbody>
    <body name="link" pos="0 0 1">
      <joint name="hinge" type="hinge" axis="0 1 0" damping="0.1"/>
      <geom name="link" type="capsule" fromto="0 0 0 0 0 -0.5" size="0.03" mass="1.0"/>
    </body>
  </worldbody>
  <actuator>
    <general name="motor" joint="hinge" dyntype="filter" dynprm="0.05" gainprm="2"/>
  </actuator>
</mujoco>)";

// act residuals (and qpos, qvel) of a filter actuator: time constant 0.05 s (start 0.1) and the
// hinge's damping 0.1 (start 0.3) as a `field` and a kind, noise-free; x_0 a variable. Tolerance
// 1e-4 column-scaled, as the sensor check
TEST(StateResidualsTest, ActivationJacobiansAgreeWithCeres) {
  ModelPtr m = LoadModelFromString(kFiltered);
  ASSERT_EQ(m->na, 1);
  InitialState x0;
  x0.qpos = Eigen::VectorXd::Constant(1, 0.3);
  const int T = 150;
  const RowMatrix u = Excitation(*m, T, 1.0, 9);
  ParameterSpec tau;
  tau.kind = "field";
  tau.field = "actuator_dynprm";
  tau.index = 0;
  const std::vector<Truth> truth = {{"tau", tau, 0.05},
                                    {"damping", Spec("joint_damping", "hinge"), 0.1}};
  FitSequence sq = StateLog(*m, truth, x0, u, T, Eigen::VectorXd(), 0, 0, 0);
  // the activations of the true rollout
  Simulator sim(*m, {tau});
  sim.SetParameters(Eigen::VectorXd::Constant(1, 0.05));
  const Trajectory tr = sim.Rollout(SequenceInput{x0, u});
  sq.act = tr.states.topRows(T).rightCols(1);
  Problem problem;
  problem.AddModel("m", *m);
  problem.AddParameter(FitParameter("tau", tau, 0.1).Bounds(1e-3, 1).Log());
  problem.AddParameter(FitParameter("damping", truth[1].spec, 0.3).Bounds(1e-3, 10).Log());
  problem.AddSequence(sq);
  FitOptions opt;
  opt.states = QposQvel(1e-3, 1e-2);
  opt.states.act.fit = true;
  opt.states.act.sigma = {1e-2};
  opt.estimate_initial_state = true;
  const JacobianCheck check = problem.CheckJacobians(opt);
  PrintCheck(check);
  EXPECT_GE(check.per_variable.size(), 3u);
  EXPECT_LE(check.worst_relative_error, 1e-4) << check.worst_where;
  const FitResult r = problem.Fit(opt);
  EXPECT_NEAR(Estimate(r, "tau").value, 0.05, 0.05 * 1e-6);
  EXPECT_EQ(r.sequences[0].state_names.back(), "act:motor");
}

// A model without sensors fitted from its logged states alone (qpos, qvel of both hinges, 1000
// steps): truth damping 0.2, mass 1.0, start 0.05 and 2.0. Noise-free: relative error <= 1e-6.
// With noise (sigma 1e-3 rad on qpos, 1e-2 rad/s on qvel, seed 7): converged, the truth inside
// the 95 % intervals, the weighted residual variance near 1 (0.8 .. 1.2)
TEST(StateResidualsTest, RecoversDampingAndMassWithoutSensors) {
  ModelPtr m = LoadModelFromString(test::kChainXml);
  ASSERT_EQ(m->nsensordata, 0);
  InitialState x0;
  x0.qpos = Eigen::Vector2d(0.4, -0.3);
  const int T = 1000;
  const RowMatrix u = Excitation(*m, T, 2.0, 6);
  const std::vector<Truth> truth = {{"damping", Spec("joint_damping", "hinge1"), 0.2},
                                    {"mass", Spec("body_mass", "link1"), 1.0}};
  for (const double noise : {0.0, 1.0}) {
    const FitSequence sq =
        StateLog(*m, truth, x0, u, T, Eigen::VectorXd(), 1e-3 * noise, 1e-2 * noise, 7);
    Problem problem;
    problem.AddModel("m", *m);
    problem.AddParameter(FitParameter("damping", truth[0].spec, 0.05).Bounds(1e-3, 10).Log());
    problem.AddParameter(FitParameter("mass", truth[1].spec, 2.0).Bounds(0.1, 10).Log());
    problem.AddSequence(sq);
    FitOptions opt;
    opt.states = QposQvel(1e-3, 1e-2);
    const FitResult r = problem.Fit(opt);
    std::printf("[ measured ] noise %g: cost %.3e -> %.3e, %d iterations, %s, chi2 %.3f\n", noise,
                r.initial_cost, r.final_cost, r.iterations, FitStatusName(r.outcome), r.chi2_ratio);
    for (const Truth& t : truth) {
      const ParameterEstimate& e = Estimate(r, t.name);
      std::printf("[ measured ]   %s %.9g +- %.3g (truth %g)\n", t.name.c_str(), e.value,
                  e.std_error, t.value);
      if (noise == 0) {
        EXPECT_NEAR(e.value / t.value, 1.0, 1e-6) << t.name;
      } else {
        EXPECT_LE(e.ci95_low, t.value) << t.name;
        EXPECT_GE(e.ci95_high, t.value) << t.name;
      }
    }
    ASSERT_EQ(r.sequences.size(), 1u);
    const SequenceResult& sr = r.sequences[0];
    EXPECT_EQ(sr.state_names, (std::vector<std::string>{"qpos:hinge1", "qpos:hinge2", "qvel:hinge1",
                                                        "qvel:hinge2"}));
    EXPECT_EQ(sr.state_measured.rows(), T);
    EXPECT_EQ(sr.state_simulated_final.cols(), 4);
    if (noise > 0) {
      EXPECT_EQ(r.outcome, FitStatus::kConverged);
      EXPECT_TRUE(r.intervals_valid);
      EXPECT_GT(r.chi2_ratio, 0.8);
      EXPECT_LT(r.chi2_ratio, 1.2);
      EXPECT_EQ(r.sensor_chi2_ratio.count("qpos:hinge1"), 1u);
    }
  }
}

// The same noisy data fitted once as jointpos/jointvel sensors (sigmas given) and once as logged
// states: the double pendulum's sensors q1, q2, v1, v2 are its qpos and qvel, so both fits must
// agree. Truth damping 0.05 on both hinges (the model says 0.02), start 0.01, noise 1e-3 rad /
// 1e-2 rad/s (seed 3), 800 steps: estimates equal to 1e-9 relative, standard errors to 1e-6, the
// same chi-square ratio (1e-8)
TEST(StateResidualsTest, StatesFitLikeTheEquivalentSensors) {
  ModelPtr m = LoadModel(std::string(MJSYSID_MODELS_DIR) + "/double_pendulum.xml");
  InitialState x0;
  x0.qpos = Eigen::Vector2d(0.5, -0.2);
  const int T = 800;
  const RowMatrix u = Excitation(*m, T, 1.0, 2);
  const std::vector<Truth> truth = {{"d1", Spec("joint_damping", "hinge1"), 0.05},
                                    {"d2", Spec("joint_damping", "hinge2"), 0.05}};
  FitSequence sq = StateLog(*m, truth, x0, u, T, Eigen::VectorXd(), 1e-3, 1e-2, 3);
  sq.measured.resize(T, 4);
  sq.measured << sq.qpos, sq.qvel;
  FitResult r[2];
  for (int as_states = 0; as_states < 2; ++as_states) {
    Problem problem;
    problem.AddModel("m", *m);
    for (const Truth& t : truth) {
      problem.AddParameter(FitParameter(t.name, t.spec, 0.01).Bounds(1e-4, 10).Log());
    }
    FitSequence s = sq;
    FitOptions opt;
    if (as_states) {
      s.no_sensors = true;
      s.measured.setConstant(std::nan(""));  // no sensor data
      opt.states = QposQvel(1e-3, 1e-2);
    } else {
      opt.sensor_weights = {{"q1", 1e3}, {"q2", 1e3}, {"v1", 1e2}, {"v2", 1e2}};
      opt.sensors_with_sigma = {"q1", "q2", "v1", "v2"};
    }
    problem.AddSequence(s);
    r[as_states] = problem.Fit(opt);
  }
  for (const Truth& t : truth) {
    const ParameterEstimate &a = Estimate(r[0], t.name), &b = Estimate(r[1], t.name);
    std::printf("[ measured ] %s: sensors %.12g +- %.6g, states %.12g +- %.6g\n", t.name.c_str(),
                a.value, a.std_error, b.value, b.std_error);
    EXPECT_NEAR(b.value / a.value, 1.0, 1e-9);
    // the Jacobians come by two finite-difference paths (dy = C dx + D du from mjd_transitionFD
    // vs the state rows themselves), equal to their O(1e-6) step error: measured 1.3e-8
    EXPECT_NEAR(b.std_error / a.std_error, 1.0, 1e-6);
  }
  std::printf("[ measured ] chi2 sensors %.9f, states %.9f\n", r[0].chi2_ratio, r[1].chi2_ratio);
  std::printf("[ measured ] sensors: %d iterations, %lld steps, %.3f s; states: %d, %lld, %.3f s\n",
              r[0].iterations, r[0].diagnostics.simulation_steps, r[0].seconds, r[1].iterations,
              r[1].diagnostics.simulation_steps, r[1].seconds);
  EXPECT_NEAR(r[1].chi2_ratio / r[0].chi2_ratio, 1.0, 1e-8);
}

// A qpos log with a NaN sample: masked (one residual row fewer, warned), not an error
TEST(StateResidualsTest, NanSamplesAreMasked) {
  ModelPtr m = LoadModelFromString(test::kChainXml);
  InitialState x0;
  x0.qpos = Eigen::Vector2d(0.4, -0.3);
  const int T = 300;
  const RowMatrix u = Excitation(*m, T, 2.0, 6);
  const std::vector<Truth> truth = {{"damping", Spec("joint_damping", "hinge1"), 0.2}};
  FitSequence sq = StateLog(*m, truth, x0, u, T, Eigen::VectorXd(), 0, 0, 0);
  sq.qpos(10, 1) = std::nan("");
  Problem problem;
  problem.AddModel("m", *m);
  problem.AddParameter(FitParameter("damping", truth[0].spec, 0.5).Bounds(1e-3, 10).Log());
  problem.AddSequence(sq);
  FitOptions opt;
  opt.states.qpos.fit = true;
  opt.states.qpos.sigma = {1e-3};
  const FitResult r = problem.Fit(opt);
  EXPECT_EQ(r.num_residuals, 2 * T - 1);
  EXPECT_NEAR(Estimate(r, "damping").value, 0.2, 1e-6);
  bool warned = false;
  for (const auto& w : r.warnings) warned = warned || w.find("qpos:hinge2") != std::string::npos;
  EXPECT_TRUE(warned);
}

// bad input: unknown joint (with a hint), sigma <= 0, a sigma count that fits no rule, a log
// without the qpos the fit needs, an actuator without activation
TEST(StateResidualsTest, BadInputIsNamed) {
  ModelPtr m = LoadModelFromString(test::kChainXml);
  InitialState x0;
  const RowMatrix u = Excitation(*m, 50, 1.0, 1);
  auto fit_error = [&](const FitStates& st, bool with_qpos) {
    FitSequence sq = StateLog(*m, {}, x0, u, 50, Eigen::VectorXd(), 0, 0, 0);
    if (!with_qpos) sq.qpos.resize(0, 0);
    Problem problem;
    problem.AddModel("m", *m);
    problem.AddParameter(
        FitParameter("damping", Spec("joint_damping", "hinge1"), 0.5).Bounds(1e-3, 10));
    problem.AddSequence(sq);
    FitOptions opt;
    opt.states = st;
    try {
      problem.Fit(opt);
    } catch (const std::invalid_argument& e) {
      return std::string(e.what());
    }
    return std::string("no error");
  };
  FitStates st = QposQvel(1e-3, 1e-2);
  st.qpos.names = {"hinge3"};
  EXPECT_NE(fit_error(st, true).find("states.qpos: no joint named 'hinge3'; did you mean"),
            std::string::npos)
      << fit_error(st, true);
  st = QposQvel(0, 1e-2);
  EXPECT_NE(fit_error(st, true).find("states.qpos: sigma must be positive"), std::string::npos);
  st = QposQvel(1e-3, 1e-2);
  st.qvel.names = {"hinge1", "hinge2"};
  st.qvel.sigma = {1, 2, 3};
  EXPECT_NE(fit_error(st, true).find("states.qvel: sigma needs one shared value or one per name"),
            std::string::npos);
  st = QposQvel(1e-3, 1e-2);
  EXPECT_NE(fit_error(st, false).find("sequence 'seq0': states.qpos are fitted but the log has no "
                                      "qpos"),
            std::string::npos)
      << fit_error(st, false);
  st = FitStates();
  st.act.fit = true;
  st.act.names = {"torque1"};
  st.act.sigma = {1};
  EXPECT_NE(fit_error(st, true).find("actuator 'torque1' has no activation"), std::string::npos);
}

}  // namespace
}  // namespace mjsysid
