// Stress: every integrator MuJoCo offers (Euler, implicit, implicitfast, RK4) at tiny, default and
// large timesteps, on a double pendulum swinging moderately (not chaotic over 0.4 s).
// - directional Jacobians (forward, central) agree with central whole-rollout differences for
//   every integrator; matrix ones too except RK4, where mjd_transitionFD does not exist: an
//   explicit matrix request is a clear std::invalid_argument naming RK4 (also from Problem::Fit),
//   and auto picks directional.
// - a short noise-free fit of two joint dampings (truth 0.02, 0.02; start 0.1, 0.005) converges
//   to 1e-5 relative with every integrator.
#include <gtest/gtest.h>

#include <cstdio>
#include <string>
#include <vector>

#include "tests/stress/stress_util.h"

namespace mjsysid {
namespace {

using stress::ColumnScaledError;
using stress::Excitation;
using stress::Spec;

std::string DoublePendulumXml(const std::string& integrator, double dt) {
  char buf[2048];
  std::snprintf(buf, sizeof(buf), R"(
<mujoco>
  <option timestep="%g" integrator="%s"/>
  <worldbody>
    <body name="link1" pos="0 0 2">
      <joint name="hinge1" type="hinge" axis="0 1 0" damping="0.02"/>
      <geom name="link1" type="capsule" fromto="0 0 0 0 0 -0.5" size="0.03" mass="1.0"/>
      <body name="link2" pos="0 0 -0.5">
        <joint name="hinge2" type="hinge" axis="0 1 0" damping="0.02"/>
        <geom name="link2" type="capsule" fromto="0 0 0 0 0 -0.5" size="0.03" mass="0.8"/>
      </body>
    </body>
  </worldbody>
  <actuator><motor name="torque1" joint="hinge1" gear="1"/></actuator>
  <sensor>
    <jointpos name="q1" joint="hinge1"/><jointpos name="q2" joint="hinge2"/>
    <jointvel name="v1" joint="hinge1"/><jointvel name="v2" joint="hinge2"/>
  </sensor>
</mujoco>)",
                dt, integrator.c_str());
  return buf;
}

const char* const kIntegrators[] = {"Euler", "implicit", "implicitfast", "RK4"};

std::vector<double> Timesteps() {
  if (stress::LongMode()) return {1e-4, 5e-4, 0.002, 0.01, 0.02, 0.05};
  return {1e-4, 0.002, 0.02};
}

// tolerances (column-scaled against the oracle): forward 1e-4, central 2e-6, as in
// tests/core/simulator_test.cc; 0.4 s of simulated time at every timestep
TEST(IntegratorStressTest, JacobiansAgreeWithTheOracleForEveryIntegrator) {
  const std::vector<ParameterSpec> params = {
      Spec("body_mass", "link1"), Spec("joint_damping", "hinge1"), Spec("joint_damping", "hinge2")};
  for (const char* integrator : kIntegrators) {
    for (double dt : Timesteps()) {
      ModelPtr m = LoadModelFromString(DoublePendulumXml(integrator, dt));
      const bool rk4 = m->opt.integrator == mjINT_RK4;
      Simulator sim(*m, params);
      SequenceInput seq;
      seq.x0.qpos = Eigen::Vector2d(0.6, -0.4);
      const int T = std::max(10, static_cast<int>(0.4 / dt + 0.5));
      seq.ctrl = Excitation(*m, T, 1.0, 3);
      const Trajectory nominal = sim.Rollout(seq);
      JacobianOptions ref_opt;
      ref_opt.mode = JacobianMode::kWholeRollout;
      ref_opt.central = true;
      const Sensitivity ref = sim.Jacobians(seq, nominal, ref_opt);
      for (JacobianMode mode : {JacobianMode::kDirectional, JacobianMode::kMatrix}) {
        for (bool central : {false, true}) {
          JacobianOptions opt;
          opt.mode = mode;
          opt.central = central;
          const std::string label = std::string(integrator) + " dt=" + std::to_string(dt) + " " +
                                    JacobianModeName(mode) + (central ? "/central" : "/forward");
          if (rk4 && mode == JacobianMode::kMatrix) {
            try {
              sim.Jacobians(seq, nominal, opt);
              ADD_FAILURE() << label << ": expected std::invalid_argument";
            } catch (const std::invalid_argument& e) {
              EXPECT_NE(std::string(e.what()).find("RK4"), std::string::npos) << e.what();
              std::printf("[ stress ] integrator %-12s dt=%-7g T=%-5d %-19s refused: %s\n",
                          integrator, dt, T, "matrix", e.what());
            }
            continue;
          }
          const Sensitivity s = sim.Jacobians(seq, nominal, opt);
          const double err =
              std::max(ColumnScaledError(s.DyDp, ref.DyDp), ColumnScaledError(s.DxDp, ref.DxDp));
          const double tol = central ? 2e-6 : 1e-4;
          std::printf(
              "[ stress ] integrator %-12s dt=%-7g T=%-5d %-19s err=%.2e tol=%.0e\n", integrator,
              dt, T,
              (std::string(JacobianModeName(mode)) + (central ? "/central" : "/forward")).c_str(),
              err, tol);
          EXPECT_LE(err, tol) << label;
          EXPECT_TRUE(s.warnings.empty()) << label << ": " << s.warnings[0];
        }
      }
      if (rk4) {
        // auto never picks the matrix chain for RK4, even with many columns where it would be
        // cheaper (the initial state adds nx = 4 columns)
        JacobianOptions many;
        many.initial_state = true;
        EXPECT_EQ(sim.ChooseJacobianMode(many, 0.0), JacobianMode::kDirectional);
        EXPECT_EQ(sim.Jacobians(seq, nominal, many).mode, JacobianMode::kDirectional);
      }
    }
  }
}

// truth damping 0.02 on both hinges; start 0.1 and 0.005; noise-free; relative error <= 1e-5;
// 1 s of data at dt = 0.002 (0.01 for the long mode's extra runs is not needed: one dt)
TEST(IntegratorStressTest, ShortFitConvergesWithEveryIntegrator) {
  for (const char* integrator : kIntegrators) {
    ModelPtr m = LoadModelFromString(DoublePendulumXml(integrator, 0.002));
    const std::vector<stress::Truth> truth = {{"b1", Spec("joint_damping", "hinge1"), 0.02},
                                              {"b2", Spec("joint_damping", "hinge2"), 0.02}};
    InitialState x0;
    x0.qpos = Eigen::Vector2d(0.6, -0.4);
    const RowMatrix u = Excitation(*m, 500, 1.0, 4);
    const RowMatrix y = stress::Measure(*m, truth, x0, u, 0, 0);
    auto fit = [&](JacobianMode mode) {
      Problem problem;
      problem.AddModel("dp", *m);
      problem.AddParameter(FitParameter("b1", truth[0].spec, 0.1).Bounds(1e-5, 10).Log());
      problem.AddParameter(FitParameter("b2", truth[1].spec, 0.005).Bounds(1e-5, 10).Log());
      problem.AddSequence(FitSequence("s", "dp", x0, u, y));
      FitOptions opt;
      opt.threads = 2;
      opt.jacobian.mode = mode;
      return problem.Fit(opt);
    };
    const FitResult r = fit(JacobianMode::kAuto);
    const double err = stress::WorstRelativeError(r, truth);
    std::printf("[ stress ] integrator fit %-12s jacobian %-11s error %.2e, %d iterations\n",
                integrator, r.diagnostics.jacobian_mode.c_str(), err, r.iterations);
    EXPECT_TRUE(r.converged) << integrator << ": " << TerminationText(r.termination);
    EXPECT_LE(err, 1e-5) << integrator;
    if (m->opt.integrator == mjINT_RK4) {
      EXPECT_EQ(r.diagnostics.jacobian_mode, "directional");
      try {
        fit(JacobianMode::kMatrix);
        ADD_FAILURE() << "RK4 with jacobian mode matrix: expected std::invalid_argument";
      } catch (const std::invalid_argument& e) {
        EXPECT_NE(std::string(e.what()).find("RK4"), std::string::npos) << e.what();
      }
    }
  }
}

}  // namespace
}  // namespace mjsysid
