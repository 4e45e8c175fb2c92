// rollouts and chained Jacobians of the simulator: time convention, agreement of the three modes
// with central whole-rollout differences, a closed-form oracle, thread-count invariance, failures,
// recovery after MuJoCo errors, constraint-solver warnings
#include "core/simulator.h"

#include <gtest/gtest.h>

#include <atomic>
#include <cmath>
#include <cstdio>
#include <string>
#include <vector>

#include "core/mujoco_env.h"
#include "tests/test_util.h"

namespace mjsysid {
namespace {

const std::string kModels = MJSYSID_MODELS_DIR;

using test::Spec;

// sine controls: actuator i gets amplitude * sin(w_i t + phase_i) + offset
RowMatrix SineControls(const mjModel& m, int T, double amplitude, double offset = 0) {
  RowMatrix u(T, m.nu);
  for (int k = 0; k < T; ++k) {
    for (int i = 0; i < m.nu; ++i) {
      u(k, i) = offset +
                amplitude * std::sin(2.0 * M_PI * (0.7 + 0.45 * i) * k * m.opt.timestep + 0.5 * i);
    }
  }
  return u;
}

// ---------------------------------------------------------------------------------------------
// time convention: y_k = h(x_k, u_k), x_{k+1} = f(x_k, u_k)

TEST(SimulatorTest, SensorsAreComputedAtTheStateBeforeTheStep) {
  ModelPtr m = LoadModel(kModels + "/pendulum.xml");
  Simulator sim(*m, {});
  SequenceInput seq;
  seq.x0 = sim.ReferenceState();
  seq.x0.qpos[0] = 0.4;
  seq.ctrl = SineControls(sim.model(), 50, 1.0);
  const Trajectory tr = sim.Rollout(seq);
  ASSERT_EQ(tr.T, 50);
  ASSERT_EQ(tr.states.rows(), 51);
  ASSERT_EQ(tr.sensors.rows(), 50);

  // independent check with plain MuJoCo calls on the simulator's model
  DataPtr d = MakeData(sim.model());
  d->qpos[0] = 0.4;
  for (int k = 0; k < 50; ++k) {
    d->ctrl[0] = seq.ctrl(k, 0);
    // y_k: mj_forward at x_k with u_k
    mj_forward(&sim.model(), d.get());
    EXPECT_EQ(tr.states(k, 0), d->qpos[0]) << k;
    EXPECT_EQ(tr.sensors(k, 0), d->sensordata[0]) << "angle sensor at x_k, step " << k;
    EXPECT_EQ(tr.sensors(k, 1), d->sensordata[1]) << "rate sensor at x_k, step " << k;
    mj_step(&sim.model(), d.get());
  }
  EXPECT_EQ(tr.states(50, 0), d->qpos[0]);
  EXPECT_EQ(tr.states(50, 1), d->qvel[0]);
}

TEST(SimulatorTest, UsersModelIsNotModifiedAndOptionsAreRecorded) {
  ModelPtr m = LoadModel(kModels + "/cartpole.xml");
  const double tolerance = m->opt.tolerance;
  Simulator sim(*m, {Spec("body_mass", "pole")});
  Eigen::VectorXd p(1);
  p << 0.5;
  sim.SetParameters(p);
  EXPECT_EQ(m->body_mass[mj_name2id(m.get(), mjOBJ_BODY, "pole")], 0.2);
  EXPECT_EQ(m->opt.tolerance, tolerance);
  EXPECT_EQ(sim.model().opt.tolerance, 1e-10) << "tight solver tolerance on the private copy";
  SimulatorOptions fixed;
  fixed.fixed_solver_iterations = true;
  EXPECT_EQ(Simulator(*m, {}, fixed).model().opt.tolerance, 0.0);
  EXPECT_EQ(sim.GetParameters()[0], 0.5);
}

// ---------------------------------------------------------------------------------------------
// Jacobians against central whole-rollout differences

struct JacobianCase {
  std::string model;
  std::vector<ParameterSpec> params;
  double amplitude, offset;  // controls
  double qvel0;              // initial velocity of every dof (moves frictional joints off zero)
  std::string name;
  int settle_steps;  // steps at zero control before the test's initial state (rest in contact)
  double tolerance_scale = 1;  // a case's own measured factor on the tolerances below
};

// error of J against the reference R, each column scaled by the reference's largest entry
double ColumnScaledError(const RowMatrix& J, const RowMatrix& R) {
  double worst = 0;
  for (Eigen::Index j = 0; j < R.cols(); ++j) {
    const double scale = std::max(R.col(j).lpNorm<Eigen::Infinity>(), 1e-12);
    worst = std::max(worst, (J.col(j) - R.col(j)).lpNorm<Eigen::Infinity>() / scale);
  }
  return worst;
}

class JacobianTest
    : public ::testing::TestWithParam<std::tuple<JacobianCase, int /*T*/, bool /*initial*/>> {};

TEST_P(JacobianTest, ModesAgreeWithCentralWholeRolloutDifferences) {
  const auto& [c, T, initial] = GetParam();
  ModelPtr m = LoadModel(kModels + "/" + c.model);
  Simulator sim(*m, c.params);
  SequenceInput seq;
  seq.x0 = sim.ReferenceState();
  seq.x0.qvel.setConstant(c.qvel0);
  if (c.settle_steps > 0) {
    SequenceInput settle{seq.x0, RowMatrix::Zero(c.settle_steps, m->nu)};
    const Trajectory rest = sim.Rollout(settle);
    seq.x0.qpos = rest.states.row(c.settle_steps).head(m->nq);
    seq.x0.qvel = rest.states.row(c.settle_steps).segment(m->nq, m->nv);
  }
  seq.ctrl = SineControls(sim.model(), T, c.amplitude, c.offset);
  const Trajectory nominal = sim.Rollout(seq);

  // with one step, y_0 does not depend on the parameters and a control that is zero at k = 0
  // leaves a gain column zero: that is right, not an error
  JacobianOptions ref_opt;
  ref_opt.zero_column_is_error = T > 1;
  ref_opt.mode = JacobianMode::kWholeRollout;
  ref_opt.central = true;
  ref_opt.initial_state = initial;
  const Sensitivity ref = sim.Jacobians(seq, nominal, ref_opt);
  ASSERT_GT(ref.DxDp.lpNorm<Eigen::Infinity>(), 0);

  // tolerances (column-scaled max error): forward differences have truncation error O(h) with
  // h = 1e-6 relative, so 1e-4 leaves two orders of headroom for curvature and for the growth of
  // the error through T steps; central differences are O(h^2) + roundoff O(eps/h) ~ 1e-10, so
  // 2e-6 is loose by the same margin. Contact scenes get 10x more: the solver's fixed iteration
  // count leaves a non-smooth residual in each step.
  const bool contact =
      sim.model().ngeom > 1 && (c.model == "box_floor.xml" || c.model == "box_pair.xml");
  // native delays (history buffers): the one-step modes are refused, auto takes whole rollouts,
  // and forward whole-rollout differences agree with the central reference
  if (sim.model().nhistory > 0) {
    for (JacobianMode mode : {JacobianMode::kDirectional, JacobianMode::kMatrix}) {
      JacobianOptions opt;
      opt.mode = mode;
      EXPECT_THROW(sim.Jacobians(seq, nominal, opt), std::invalid_argument);
    }
    JacobianOptions opt;
    opt.initial_state = initial;
    opt.zero_column_is_error = ref_opt.zero_column_is_error;
    const Sensitivity s = sim.Jacobians(seq, nominal, opt);
    EXPECT_EQ(s.mode, JacobianMode::kWholeRollout);
    EXPECT_LE(ColumnScaledError(s.DyDp, ref.DyDp), 1e-4);
    EXPECT_LE(ColumnScaledError(s.DxDp, ref.DxDp), 1e-4);
    return;
  }
  for (JacobianMode mode : {JacobianMode::kDirectional, JacobianMode::kMatrix}) {
    for (bool central : {false, true}) {
      JacobianOptions opt;
      opt.mode = mode;
      opt.central = central;
      opt.initial_state = initial;
      opt.zero_column_is_error = ref_opt.zero_column_is_error;
      const Sensitivity s = sim.Jacobians(seq, nominal, opt);
      EXPECT_EQ(s.mode, mode);
      const double tol = (central ? 2e-6 : 1e-4) * (contact ? 10 : 1) * c.tolerance_scale;
      const double ey = ColumnScaledError(s.DyDp, ref.DyDp);
      const double ex = ColumnScaledError(s.DxDp, ref.DxDp);
      EXPECT_LE(ey, tol) << JacobianModeName(mode) << (central ? " central" : " forward")
                         << " sensors";
      EXPECT_LE(ex, tol) << JacobianModeName(mode) << (central ? " central" : " forward")
                         << " states";
      std::printf("[ measured ] %-16s T=%-3d x0=%d %-11s %-7s err(dy)=%.2e err(dx)=%.2e tol=%.0e\n",
                  c.name.c_str(), T, initial ? 1 : 0, JacobianModeName(mode),
                  central ? "central" : "forward", ey, ex, tol);
    }
  }
}

const std::vector<JacobianCase> kCases = {
    {"pendulum.xml",
     {Spec("joint_damping", "hinge"), Spec("joint_frictionloss", "hinge"), Spec("body_mass", "bob"),
      Spec("actuator_gain", "torque")},
     2.0,
     0.0,
     1.0,
     "pendulum",
     {}},
    {"double_pendulum.xml",
     {Spec("body_mass", "link1"), Spec("body_mass", "link2"), Spec("joint_damping", "hinge2")},
     1.0,
     0.0,
     0.5,
     "double_pendulum",
     {}},
    {"cartpole.xml",
     {Spec("body_mass", "pole"), Spec("joint_damping", "slider"),
      Spec("joint_frictionloss", "slider")},
     8.0,
     0.0,
     0.5,
     "cartpole",
     {}},
    {"arm5.xml",
     {Spec("joint_armature", "j1"), Spec("joint_armature", "j3"), Spec("joint_damping", "j2"),
      Spec("body_mass_inertia", "link4"), Spec("body_com", "link5", 2)},
     1.0,
     0.0,
     0.3,
     "arm5",
     {}},
    // the box first settles on the floor: at its qpos0 (exactly zero distance) the contact
    // switches on, and an initial-state derivative there is not defined
    {"box_floor.xml",
     {Spec("geom_friction", "box", 0), Spec("body_mass", "box")},
     5.0,
     15.0,
     0.0,
     "box_floor",
     1000},
    {"ball_pendulum.xml",
     {Spec("joint_damping", "ball"), Spec("body_mass", "bob"), Spec("joint_armature", "ball")},
     0.5,
     0.0,
     0.7,
     "ball_pendulum",
     {}},
    // robot-grade kinds: servo gains and the full inertia of the last link (log-Cholesky alpha,
    // d2; its s and t variables are zero or near it, where the step floor 1e-3 makes h = 1e-9 m
    // and the difference roundoff-bound: docs/numerics.md)
    {"arm7.xml",
     {Spec("actuator_kp", "s2"), Spec("actuator_kv", "s4"), Spec("body_inertial", "link7", 0),
      Spec("body_inertial", "link7", 2)},
     0.8,
     0.0,
     0.3,
     "arm7_servo_inertial",
     {}},
    // a pid's three gains, a velocity servo, a tendon's four kinds, a full inertia's d1 and t1
    // (its s variables are a few mm: the same step floor limit as above)
    {"pid_tendon.xml",
     {Spec("actuator_kp", "shoulder_pid"), Spec("actuator_ki", "shoulder_pid"),
      Spec("actuator_kv", "shoulder_pid"), Spec("actuator_kv", "elbow_vel"),
      Spec("tendon_stiffness", "coupling"), Spec("tendon_damping", "coupling"),
      Spec("tendon_frictionloss", "coupling"), Spec("tendon_lengthspring", "coupling", 0),
      Spec("body_inertial", "lower", 1), Spec("body_inertial", "lower", 7)},
     1.0,
     0.0,
     0.4,
     "pid_tendon",
     {}},
    // an explicit contact pair's friction and softness (the box settled on the floor first)
    {"box_pair.xml",
     {Spec("pair_friction", "box_floor", 0), Spec("pair_solref", "box_floor", 0),
      Spec("pair_solimp", "box_floor", 0)},
     5.0,
     15.0,
     0.0,
     "box_pair",
     1000},
    // native delays (history buffers): the actuator's and the sensor's delay, and a servo gain
    {"servo_delay.xml",
     {Spec("actuator_delay", "servo"), Spec("sensor_delay", "angle"), Spec("actuator_kp", "servo")},
     0.8,
     0.0,
     0.3,
     "servo_delay",
     {}},
    // a voltage-input DC motor: constant, resistance, inductance, cogging
    {"dcmotor.xml",
     {Spec("dcmotor_motorconst", "motor"), Spec("dcmotor_resistance", "motor"),
      Spec("dcmotor_inductance", "motor"), Spec("dcmotor_cogging", "motor", 0)},
     3.0,
     0.0,
     0.5,
     "dcmotor",
     {}},
    // contact softness of a geom (the box settled on the floor first)
    {"box_floor.xml",
     {Spec("geom_solref", "box", 0), Spec("geom_solimp", "box", 0),
      Spec("geom_friction", "box", 0)},
     5.0,
     15.0,
     0.0,
     "box_floor_softness",
     1000},
    // tendon springs with a dead band: the lower end of one, the upper end of the other
    {"tendon_deadband.xml",
     {Spec("tendon_lengthspring", "coupling", 1), Spec("tendon_lengthspring", "elbow_band", 2),
      Spec("tendon_stiffness", "coupling")},
     1.0,
     0.0,
     0.4,
     "tendon_deadband",
     {}},
    // native sensor delays on a three-dimensional sensor and a second delayed sensor
    {"sensor_delay3.xml",
     {Spec("sensor_delay", "tip_pos"), Spec("sensor_delay", "rate"),
      Spec("joint_damping", "hinge")},
     1.0,
     0.0,
     0.5,
     "sensor_delay3",
     {}},
    // issue 16's remaining indices (the coverage table in docs/numerics.md): every entry of a
    // geom's and a pair's solref and solimp on the pressed sphere (one contact at every step),
    // settled first: at its qpos0 the penetration is exactly solimp's width, where the impedance
    // switches from its polynomial to dmax. Own tolerance (x20): the impedance's curvature in the
    // penetration parts forward differences from the central reference by up to 5.4e-4 (T = 200;
    // central: 2.0e-7); 2e-3 and 4e-5 still fail on a wrong or dropped column (error ~1)
    {"sphere_press.xml",
     {Spec("geom_solref", "sphere", 0), Spec("geom_solref", "sphere", 1),
      Spec("geom_solimp", "sphere", 0), Spec("geom_solimp", "sphere", 1),
      Spec("geom_solimp", "sphere", 2), Spec("geom_solimp", "sphere", 3),
      Spec("geom_solimp", "sphere", 4)},
     2.0,
     0.0,
     0.0,
     "sphere_press_softness",
     500,
     20},
    {"sphere_press_pair.xml",
     {Spec("pair_solref", "press", 0), Spec("pair_solref", "press", 1),
      Spec("pair_solimp", "press", 0), Spec("pair_solimp", "press", 1),
      Spec("pair_solimp", "press", 2), Spec("pair_solimp", "press", 3),
      Spec("pair_solimp", "press", 4)},
     2.0,
     0.0,
     0.0,
     "sphere_press_pair_softness",
     500,
     20},
    // the pair's second tangent coefficient (the box settled on the floor first)
    {"box_pair.xml",
     {Spec("pair_friction", "box_floor", 1)},
     5.0,
     15.0,
     0.0,
     "box_pair_friction1",
     1000},
    // cogging periods per revolution and phase. Own tolerance (x5): the one-step modes' central
    // differences part from the rollout's by up to 3.1e-6 (matrix, T = 200), as the dcmotor
    // model's other columns do with faster electrical dynamics (models/dcmotor.xml)
    {"dcmotor.xml",
     {Spec("dcmotor_cogging", "motor", 1), Spec("dcmotor_cogging", "motor", 2)},
     3.0,
     0.0,
     0.5,
     "dcmotor_cogging",
     {},
     5},
    // all 10 log-Cholesky variables of a tilted payload whose s and t are centimetre-scale
    {"payload_gimbal.xml",
     {Spec("body_inertial", "payload", 0), Spec("body_inertial", "payload", 1),
      Spec("body_inertial", "payload", 2), Spec("body_inertial", "payload", 3),
      Spec("body_inertial", "payload", 4), Spec("body_inertial", "payload", 5),
      Spec("body_inertial", "payload", 6), Spec("body_inertial", "payload", 7),
      Spec("body_inertial", "payload", 8), Spec("body_inertial", "payload", 9)},
     0.8,
     0.0,
     0.3,
     "payload_gimbal_inertial",
     {}},
};

INSTANTIATE_TEST_SUITE_P(Models, JacobianTest,
                         ::testing::Combine(::testing::ValuesIn(kCases),
                                            ::testing::Values(1, 10, 200), ::testing::Bool()),
                         [](const auto& param_info) {
                           const auto& p = param_info.param;
                           return std::get<0>(p).name + "_T" + std::to_string(std::get<1>(p)) +
                                  (std::get<2>(p) ? "_x0" : "");
                         });

// LuGre friction of a DC motor (a bristle state): the five entries' columns of the one-step
// modes (central) against whole-rollout central differences, starting near the Stribeck velocity
// so that every entry acts. Its own tolerance: the one-step linearisations part from the
// rollout's differences by 5.2e-6 (directional) and 2.9e-6 (matrix) column-scaled after 200
// steps (1.1e-7 after 10), above the smooth models' 2e-6; 2e-5 leaves 3x headroom and still
// fails on a column scaled by 1.001 (error 1e-3), dropped (1) or of flipped sign (2).
TEST(SimulatorTest, DcMotorLugreColumnsAgreeWithWholeRolloutDifferences) {
  ModelPtr m = LoadModel(kModels + "/dcmotor_lugre.xml");
  std::vector<ParameterSpec> params;
  for (int i = 0; i < 5; ++i) params.push_back(Spec("dcmotor_lugre", "motor", i));
  Simulator sim(*m, params);
  constexpr double kLugreTol = 2e-5;
  for (int T : {10, 200}) {
    SequenceInput seq;
    seq.x0 = sim.ReferenceState();
    seq.x0.qvel.setConstant(0.05);
    seq.ctrl = SineControls(sim.model(), T, 3.0, 0.0);
    const Trajectory nominal = sim.Rollout(seq);
    JacobianOptions ref_opt;
    ref_opt.mode = JacobianMode::kWholeRollout;
    ref_opt.central = true;
    const Sensitivity ref = sim.Jacobians(seq, nominal, ref_opt);
    for (JacobianMode mode : {JacobianMode::kDirectional, JacobianMode::kMatrix}) {
      JacobianOptions opt;
      opt.mode = mode;
      opt.central = true;
      const Sensitivity s = sim.Jacobians(seq, nominal, opt);
      const double ey = ColumnScaledError(s.DyDp, ref.DyDp);
      const double ex = ColumnScaledError(s.DxDp, ref.DxDp);
      std::printf("[ measured ] dcmotor_lugre T=%-3d %-11s err(dy)=%.2e err(dx)=%.2e tol=%.0e\n", T,
                  JacobianModeName(mode), ey, ex, kLugreTol);
      EXPECT_LE(ey, kLugreTol) << JacobianModeName(mode) << " T=" << T;
      EXPECT_LE(ex, kLugreTol) << JacobianModeName(mode) << " T=" << T;
    }
  }
}

// a pair's torsional and rolling friction (models/ball_roll_pair.xml: a free ball pushed into
// rolling and twisted, condim 6): the parameter columns of the one-step modes against
// whole-rollout central differences. Its own tolerance: the rolling ball's rollout is smooth only
// to about 1e-4 relative in these entries (docs/numerics.md, kind coverage), and the columns part
// by up to 1.5e-4 (central) and 3.0e-4 (forward) after 200 steps (measured; with initial-state
// columns by 5e-3, so they are left out); 1e-3 leaves 3x headroom and still fails on a column
// scaled by 1.01 (error 1e-2), dropped (1) or of flipped sign (2).
TEST(SimulatorTest, PairTorsionalRollingFrictionColumnsAgreeWithWholeRolloutDifferences) {
  ModelPtr m = LoadModel(kModels + "/ball_roll_pair.xml");
  Simulator sim(*m, {Spec("pair_friction", "roll", 2), Spec("pair_friction", "roll", 3),
                     Spec("pair_friction", "roll", 4)});
  constexpr double kRollTol = 1e-3;
  for (int T : {10, 200}) {
    SequenceInput seq;
    seq.x0 = sim.ReferenceState();
    seq.ctrl = SineControls(sim.model(), T, 0.3, 0.5);
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
        const Sensitivity s = sim.Jacobians(seq, nominal, opt);
        const double ey = ColumnScaledError(s.DyDp, ref.DyDp);
        const double ex = ColumnScaledError(s.DxDp, ref.DxDp);
        std::printf(
            "[ measured ] pair torsional/rolling T=%-3d %-11s %-7s err(dy)=%.2e err(dx)=%.2e "
            "tol=%.0e\n",
            T, JacobianModeName(mode), central ? "central" : "forward", ey, ex, kRollTol);
        EXPECT_LE(ey, kRollTol) << JacobianModeName(mode) << " T=" << T;
        EXPECT_LE(ex, kRollTol) << JacobianModeName(mode) << " T=" << T;
      }
    }
  }
}

// ---------------------------------------------------------------------------------------------
// closed-form oracle: spring-mass-damper on a slide joint under MuJoCo's Euler integrator, which
// is semi-implicit in velocity and implicit in damping:
//   a_k = (u_k - b v_k - k x_k) / (m + h b),  v_{k+1} = v_k + h a_k,  x_{k+1} = x_k + h v_{k+1}
// differentiated exactly with respect to m, b and k.

struct OracleResult {
  std::vector<double> x, v;          // x_0..x_T, v_0..v_T
  std::vector<double> dx[3], dv[3];  // d/dm, d/db, d/dk
};

OracleResult SpringMassOracle(double m, double b, double k, double h, double x0, double v0,
                              const RowMatrix& u) {
  const int T = static_cast<int>(u.rows());
  OracleResult r;
  r.x = {x0};
  r.v = {v0};
  for (auto& d : r.dx) d = {0.0};
  for (auto& d : r.dv) d = {0.0};
  for (int t = 0; t < T; ++t) {
    const double x = r.x[t], v = r.v[t];
    const double den = m + h * b, num = u(t, 0) - b * v - k * x;
    const double a = num / den;
    r.v.push_back(v + h * a);
    r.x.push_back(x + h * r.v.back());
    for (int p = 0; p < 3; ++p) {
      const double dxp = r.dx[p][t], dvp = r.dv[p][t];
      // d num / dp and d den / dp
      double dnum = -b * dvp - k * dxp, dden = 0;
      if (p == 0) dden = 1;
      if (p == 1) dnum -= v, dden = h;
      if (p == 2) dnum -= x;
      const double da = dnum / den - num * dden / (den * den);
      r.dv[p].push_back(dvp + h * da);
      r.dx[p].push_back(dxp + h * r.dv[p].back());
    }
  }
  return r;
}

TEST(OracleTest, SpringMassDamperSensitivitiesMatchClosedForm) {
  ModelPtr model = LoadModel(kModels + "/spring_mass.xml");
  Simulator sim(*model, {Spec("body_mass", "mass"), Spec("joint_damping", "slide"),
                         Spec("joint_stiffness", "slide")});
  Eigen::VectorXd p(3);
  p << 1.3, 0.4, 5.0;
  sim.SetParameters(p);
  const int T = 300;
  SequenceInput seq;
  seq.x0 = sim.ReferenceState();
  seq.x0.qpos[0] = 0.1;
  seq.x0.qvel[0] = -0.2;
  seq.ctrl = SineControls(sim.model(), T, 2.0);
  const Trajectory nominal = sim.Rollout(seq);
  const double h = sim.model().opt.timestep;
  const OracleResult o = SpringMassOracle(1.3, 0.4, 5.0, h, 0.1, -0.2, seq.ctrl);

  // the simulation is the recursion (so the oracle is an oracle for MuJoCo, not for an idea)
  for (int t = 0; t <= T; ++t) {
    ASSERT_NEAR(nominal.states(t, 0), o.x[t], 1e-12) << t;
    ASSERT_NEAR(nominal.states(t, 1), o.v[t], 1e-12) << t;
  }

  // every mode and difference scheme against the exact sensitivities, 1e-6 relative
  for (JacobianMode mode :
       {JacobianMode::kDirectional, JacobianMode::kMatrix, JacobianMode::kWholeRollout}) {
    for (bool central : {false, true}) {
      JacobianOptions opt;
      opt.mode = mode;
      opt.central = central;
      // forward differences have O(h) truncation: take a smaller relative step for them
      opt.relative_step = central ? 1e-5 : 1e-7;
      const Sensitivity s = sim.Jacobians(seq, nominal, opt);
      double worst = 0;
      for (int j = 0; j < 3; ++j) {
        double scale = 0;
        for (int t = 0; t <= T; ++t) scale = std::max(scale, std::abs(o.dx[j][t]));
        for (int t = 0; t <= T; ++t) {
          worst = std::max(worst, std::abs(s.DxDp(t * 2 + 0, j) - o.dx[j][t]) / scale);
          worst = std::max(worst, std::abs(s.DxDp(t * 2 + 1, j) - o.dv[j][t]) / scale);
          if (t < T) {  // sensors: jointpos, jointvel at x_t
            worst = std::max(worst, std::abs(s.DyDp(t * 2 + 0, j) - o.dx[j][t]) / scale);
            worst = std::max(worst, std::abs(s.DyDp(t * 2 + 1, j) - o.dv[j][t]) / scale);
          }
        }
      }
      std::printf("[ measured ] oracle %-13s %-7s max relative error %.2e\n",
                  JacobianModeName(mode), central ? "central" : "forward", worst);
      EXPECT_LE(worst, 1e-6) << JacobianModeName(mode) << (central ? " central" : " forward");
    }
  }
}

// ---------------------------------------------------------------------------------------------
// threads: every output bit-identical for any thread count

TEST(SimulatorTest, ResultsAreBitIdenticalForAnyThreadCount) {
  ModelPtr model = LoadModel(kModels + "/arm5.xml");
  const std::vector<ParameterSpec> params = {
      Spec("joint_armature", "j2"), Spec("joint_damping", "j4"), Spec("body_mass", "link3")};
  std::vector<SequenceInput> seqs(3);
  for (int i = 0; i < 3; ++i) {
    seqs[i].ctrl = SineControls(*model, 120 + 30 * i, 0.5 + 0.3 * i);
  }
  std::vector<std::vector<Sensitivity>> results;
  std::vector<std::vector<Trajectory>> rollouts;
  for (int threads : {1, 2, 3}) {
    SimulatorOptions so;
    so.threads = threads;
    Simulator sim(*model, params, so);
    ASSERT_EQ(sim.threads(), threads);
    std::vector<Trajectory> nominal;
    sim.Rollout(seqs, &nominal);
    rollouts.push_back(nominal);
    for (JacobianMode mode : {JacobianMode::kDirectional, JacobianMode::kMatrix}) {
      JacobianOptions opt;
      opt.mode = mode;
      opt.initial_state = true;
      opt.central = mode == JacobianMode::kMatrix;
      std::vector<Sensitivity> out;
      sim.Jacobians(seqs, nominal, opt, &out);
      results.push_back(out);
    }
  }
  for (size_t r = 2; r < results.size(); ++r) {
    const auto& a = results[r % 2];
    const auto& b = results[r];
    for (size_t i = 0; i < a.size(); ++i) {
      EXPECT_TRUE((a[i].DyDp.array() == b[i].DyDp.array()).all()) << "run " << r << " seq " << i;
      EXPECT_TRUE((a[i].DxDp.array() == b[i].DxDp.array()).all()) << "run " << r << " seq " << i;
    }
  }
  for (size_t r = 1; r < rollouts.size(); ++r) {
    for (size_t i = 0; i < seqs.size(); ++i) {
      EXPECT_TRUE((rollouts[0][i].states.array() == rollouts[r][i].states.array()).all());
      EXPECT_TRUE((rollouts[0][i].sensors.array() == rollouts[r][i].sensors.array()).all());
    }
  }
}

// nseq sequences of sine controls (150, 190, ... steps) and their rollouts and Jacobians on one
// thread, Rollout then Jacobians: the reference of the pipelined and columns-ahead tests
void SerialReference(const mjModel& model, const std::vector<ParameterSpec>& params, int nseq,
                     const JacobianOptions& opt, std::vector<SequenceInput>* seqs,
                     std::vector<Trajectory>* tr, std::vector<Sensitivity>* s) {
  seqs->assign(nseq, SequenceInput{});
  for (int i = 0; i < nseq; ++i) (*seqs)[i].ctrl = SineControls(model, 150 + 40 * i, 0.6);
  Simulator serial(model, params);
  serial.Rollout(*seqs, tr);
  serial.Jacobians(*seqs, *tr, opt, s);
}

// tr, s are tr1, s1 bit for bit: states, sensors, step states, contact counts, Jacobians, kinks and
// warnings
void ExpectSameRolloutAndJacobians(const Trajectory& tr, const Sensitivity& s,
                                   const Trajectory& tr1, const Sensitivity& s1,
                                   const std::string& where) {
  EXPECT_TRUE(tr.states == tr1.states) << where;
  EXPECT_TRUE(tr.sensors == tr1.sensors) << where;
  EXPECT_TRUE(tr.step == tr1.step) << where;
  EXPECT_TRUE(tr.ncon == tr1.ncon) << where;
  EXPECT_TRUE(s.DyDp == s1.DyDp) << where;
  EXPECT_TRUE(s.DxDp == s1.DxDp) << where;
  EXPECT_EQ(s.kinks, s1.kinks) << where;
  EXPECT_EQ(s.warnings, s1.warnings) << where;
}

// RolloutAndJacobians (columns pipelined behind their rollouts at 2 and 3 threads) gives what
// Rollout then Jacobians give at 1 thread, bit for bit: one and three sequences, parameter and
// initial-state columns, a model in contact (box_floor: the mode may not depend on the contacts)
TEST(SimulatorTest, PipelinedColumnsEqualRolloutThenJacobiansBitForBit) {
  struct Case {
    const char* model;
    std::vector<ParameterSpec> params;
    int nseq;
  };
  const std::vector<Case> cases = {
      {"arm5.xml", {Spec("joint_armature", "j2"), Spec("body_mass", "link3")}, 1},
      {"arm5.xml", {Spec("joint_damping", "j4")}, 3},
      {"box_floor.xml", {Spec("geom_friction", "box")}, 2}};
  for (const Case& c : cases) {
    ModelPtr model = LoadModel(kModels + "/" + c.model);
    JacobianOptions opt;
    opt.mode = JacobianMode::kDirectional;
    opt.initial_state = true;
    std::vector<SequenceInput> seqs;
    std::vector<Trajectory> tr1;
    std::vector<Sensitivity> s1;
    SerialReference(*model, c.params, c.nseq, opt, &seqs, &tr1, &s1);
    for (int threads : {2, 3}) {
      SimulatorOptions so;
      so.threads = threads;
      Simulator sim(*model, c.params, so);
      std::vector<Trajectory> tr;
      std::vector<Sensitivity> s;
      sim.RolloutAndJacobians(seqs, opt, &tr, &s);
      ASSERT_EQ(tr.size(), tr1.size());
      for (int i = 0; i < c.nseq; ++i) {
        ExpectSameRolloutAndJacobians(tr[i], s[i], tr1[i], s1[i],
                                      std::string(c.model) + " seq " + std::to_string(i));
      }
    }
  }
}

// Columns ahead (RolloutWithColumnsAhead, then Jacobians with them): the same rollouts and
// Jacobians bit for bit as Rollout then Jacobians on 1 thread, whichever columns were computed
// ahead; the columns taken are left empty; columns computed at other parameter values are not
// taken (and the result is still the same)
TEST(SimulatorTest, ColumnsAheadEqualRolloutThenJacobiansBitForBit) {
  struct Case {
    const char* model;
    std::vector<ParameterSpec> params;
    int nseq;
    bool initial_state;
  };
  const std::vector<Case> cases = {
      {"arm5.xml", {Spec("joint_armature", "j2"), Spec("body_mass", "link3")}, 3, false},
      {"arm5.xml", {Spec("joint_damping", "j4")}, 1, true},
      {"box_floor.xml", {Spec("geom_friction", "box")}, 3, false}};
  for (const Case& c : cases) {
    ModelPtr model = LoadModel(kModels + "/" + c.model);
    JacobianOptions opt;
    opt.mode = JacobianMode::kDirectional;
    opt.initial_state = c.initial_state;
    std::vector<SequenceInput> seqs;
    std::vector<Trajectory> tr1;
    std::vector<Sensitivity> s1;
    SerialReference(*model, c.params, c.nseq, opt, &seqs, &tr1, &s1);
    const int ncol = s1[0].ncol;
    for (int threads : {2, 3}) {
      SimulatorOptions so;
      so.threads = threads;
      Simulator sim(*model, c.params, so);
      for (const std::vector<int>& columns :
           {std::vector<int>{1}, std::vector<int>{ncol, 1, 0}, std::vector<int>{0, 0, ncol}}) {
        const std::string where = std::string(c.model) + " threads " + std::to_string(threads) +
                                  " columns ahead " + std::to_string(columns[0]);
        std::vector<Trajectory> tr;
        std::vector<ColumnsAhead> ahead;
        sim.RolloutWithColumnsAhead(seqs, opt, columns, &tr, &ahead);
        ASSERT_EQ(ahead.size(), seqs.size());
        for (int i = 0; i < c.nseq; ++i) {
          const int expected = i < static_cast<int>(columns.size()) ? columns[i] : 0;
          EXPECT_EQ(ahead[i].columns, expected) << where;
          EXPECT_EQ(ahead[i].steps, static_cast<long long>(expected) * tr1[i].T) << where;
        }
        std::vector<Sensitivity> s;
        sim.Jacobians(seqs, tr, opt, &ahead, &s);
        for (int i = 0; i < c.nseq; ++i) {
          EXPECT_EQ(ahead[i].columns, 0) << where << " seq " << i;  // taken
          ExpectSameRolloutAndJacobians(tr[i], s[i], tr1[i], s1[i],
                                        where + " seq " + std::to_string(i));
        }
      }
      // columns ahead at other parameter values are not taken
      std::vector<Trajectory> tr;
      std::vector<ColumnsAhead> ahead;
      const Eigen::VectorXd p = sim.GetParameters();
      sim.SetParameters(p * 1.01);
      sim.RolloutWithColumnsAhead(seqs, opt, {1}, &tr, &ahead);
      EXPECT_EQ(ahead[0].columns, 1);
      sim.SetParameters(p);
      sim.Rollout(seqs, &tr);
      std::vector<Sensitivity> s;
      sim.Jacobians(seqs, tr, opt, &ahead, &s);
      EXPECT_EQ(ahead[0].columns, 1) << c.model;  // not taken
      for (int i = 0; i < c.nseq; ++i) EXPECT_TRUE(s[i].DyDp == s1[i].DyDp) << c.model;
    }
  }
}

// RolloutAt: the rollouts at several parameter vectors in one pass are those of SetParameters and
// Rollout bit for bit, at 1, 2 and 3 threads, and leave the simulator's own values unchanged
TEST(SimulatorTest, RolloutAtEqualsSetParametersThenRolloutBitForBit) {
  ModelPtr model = LoadModel(kModels + "/arm5.xml");
  const std::vector<ParameterSpec> params = {Spec("joint_armature", "j2"),
                                             Spec("body_mass", "link3")};
  std::vector<SequenceInput> seqs(3);
  for (int i = 0; i < 3; ++i) seqs[i].ctrl = SineControls(*model, 120 + 30 * i, 0.6);
  Simulator serial(*model, params);
  const Eigen::VectorXd p0 = serial.GetParameters();
  const std::vector<Eigen::VectorXd> points = {p0 * 1.1, p0 * 0.9};
  std::vector<std::vector<Trajectory>> expected(points.size());
  for (size_t k = 0; k < points.size(); ++k) {
    serial.SetParameters(points[k]);
    serial.Rollout(seqs, &expected[k]);
  }
  for (int threads : {1, 2, 3}) {
    SimulatorOptions so;
    so.threads = threads;
    Simulator sim(*model, params, so);
    std::vector<std::vector<Trajectory>> out;
    sim.RolloutAt(seqs, points, &out);
    EXPECT_TRUE(sim.GetParameters() == p0);
    ASSERT_EQ(out.size(), points.size());
    for (size_t k = 0; k < points.size(); ++k) {
      for (int i = 0; i < 3; ++i) {
        const std::string where = "threads " + std::to_string(threads) + " point " +
                                  std::to_string(k) + " seq " + std::to_string(i);
        EXPECT_TRUE(out[k][i].states == expected[k][i].states) << where;
        EXPECT_TRUE(out[k][i].sensors == expected[k][i].sensors) << where;
        EXPECT_TRUE(out[k][i].step == expected[k][i].step) << where;
        EXPECT_TRUE(out[k][i].ncon == expected[k][i].ncon) << where;
      }
    }
    EXPECT_THROW(sim.RolloutAt(seqs, {Eigen::VectorXd(1)}, &out), std::invalid_argument);
  }
}

// a pipelined rollout that diverges is the SimulationError of Rollout (its columns stop instead of
// waiting), and the simulator then gives the results of a fresh one
TEST(SimulatorTest, PipelinedDivergenceIsASimulationErrorAndTheSimulatorStaysUsable) {
  ModelPtr model = LoadModel(kModels + "/pendulum.xml");
  model->actuator_ctrllimited[0] = 0;
  const std::vector<ParameterSpec> params = {Spec("joint_damping", "hinge")};
  SimulatorOptions so;
  so.threads = 2;
  Simulator sim(*model, params, so);
  JacobianOptions opt;
  opt.mode = JacobianMode::kDirectional;
  RowMatrix bad = RowMatrix::Zero(300, 1);
  bad.bottomRows(100).setConstant(1e200);  // from step 200 on
  std::vector<Trajectory> tr;
  std::vector<Sensitivity> s;
  try {
    sim.RolloutAndJacobians({SequenceInput{sim.ReferenceState(), bad}}, opt, &tr, &s);
    FAIL() << "expected SimulationError";
  } catch (const SimulationError& e) {
    EXPECT_EQ(e.step(), 200) << e.what();
  }
  const std::vector<SequenceInput> good = {{sim.ReferenceState(), SineControls(*model, 200, 0.5)}};
  sim.RolloutAndJacobians(good, opt, &tr, &s);
  Simulator fresh(*model, params);
  std::vector<Trajectory> tr1;
  std::vector<Sensitivity> s1;
  fresh.Rollout(good, &tr1);
  fresh.Jacobians(good, tr1, opt, &s1);
  EXPECT_TRUE(tr[0].states == tr1[0].states);
  EXPECT_TRUE(s[0].DyDp == s1[0].DyDp);
}

// ---------------------------------------------------------------------------------------------
// skip what the scene does not need

TEST(SimulatorTest, SensorsOffSkipsSensorsAndLeavesDynamicsUnchanged) {
  ModelPtr model = LoadModel(kModels + "/cartpole.xml");
  SimulatorOptions off;
  off.sensors = false;
  Simulator with(*model, {Spec("joint_damping", "slider")});
  Simulator without(*model, {Spec("joint_damping", "slider")}, off);
  SequenceInput seq{with.ReferenceState(), SineControls(*model, 100, 5.0)};
  const Trajectory a = with.Rollout(seq), b = without.Rollout(seq);
  EXPECT_EQ(b.sensors.cols(), 0);
  EXPECT_TRUE((a.states.array() == b.states.array()).all());
  for (JacobianMode mode : {JacobianMode::kDirectional, JacobianMode::kMatrix}) {
    JacobianOptions opt;
    opt.mode = mode;
    const Sensitivity sa = with.Jacobians(seq, a, opt), sb = without.Jacobians(seq, b, opt);
    EXPECT_EQ(sb.DyDp.rows(), 0);
    EXPECT_TRUE((sa.DxDp.array() == sb.DxDp.array()).all()) << JacobianModeName(mode);
  }
}

TEST(SimulatorTest, AutoModeFollowsTheCostModel) {
  ModelPtr arm = LoadModel(kModels + "/arm5.xml");
  // one parameter: a perturbed step per column beats 2 + nv + ... steps of mjd_transitionFD
  Simulator one(*arm, {Spec("joint_damping", "j1")});
  JacobianOptions opt;
  EXPECT_EQ(one.ChooseJacobianMode(opt), JacobianMode::kDirectional);
  // five velocity-stage parameters and the initial state: the matrix chain is cheaper
  Simulator many(
      *arm, {Spec("joint_damping", "j1"), Spec("joint_damping", "j2"), Spec("joint_damping", "j3"),
             Spec("joint_damping", "j4"), Spec("joint_damping", "j5")});
  opt.initial_state = true;
  EXPECT_LT(many.JacobianCostPerStep(JacobianMode::kMatrix, opt, 0.0),
            many.JacobianCostPerStep(JacobianMode::kDirectional, opt, 0.0));
  EXPECT_EQ(many.ChooseJacobianMode(opt, 0.0), JacobianMode::kMatrix);
  // with contacts at every step, forward matrix mode differences both sides: twice the cost
  EXPECT_EQ(many.ChooseJacobianMode(opt, 1.0), JacobianMode::kDirectional);
  // Jacobians() measures the share on the trajectory: the arm swings free of contacts
  SequenceInput free_swing{many.ReferenceState(), SineControls(*arm, 30, 0.5)};
  const Trajectory swing = many.Rollout(free_swing);
  EXPECT_EQ(many.Jacobians(free_swing, swing, opt).mode, JacobianMode::kMatrix);
  // RK4 has no mjd_transitionFD: auto falls back, an explicit request is an error
  ModelPtr rk4 = LoadModel(kModels + "/arm5.xml");
  rk4->opt.integrator = mjINT_RK4;
  Simulator sim_rk4(
      *rk4, {Spec("joint_damping", "j1"), Spec("joint_damping", "j2"), Spec("joint_damping", "j3"),
             Spec("joint_damping", "j4"), Spec("joint_damping", "j5")});
  EXPECT_EQ(sim_rk4.ChooseJacobianMode(opt), JacobianMode::kDirectional);
  SequenceInput seq{sim_rk4.ReferenceState(), SineControls(*rk4, 20, 1.0)};
  const Trajectory tr = sim_rk4.Rollout(seq);
  opt.mode = JacobianMode::kMatrix;
  EXPECT_THROW(sim_rk4.Jacobians(seq, tr, opt), std::invalid_argument);
  opt.mode = JacobianMode::kAuto;
  EXPECT_EQ(sim_rk4.Jacobians(seq, tr, opt).mode, JacobianMode::kDirectional);
}

// ---------------------------------------------------------------------------------------------
// failures are errors with names, never crashes or silent zeros

TEST(SimulatorTest, DivergentSimulationIsASimulationError) {
  ModelPtr model = LoadModel(kModels + "/pendulum.xml");
  model->actuator_ctrllimited[0] = 0;
  Simulator sim(*model, {});
  SequenceInput seq{sim.ReferenceState(), RowMatrix::Constant(50, 1, 1e200)};
  try {
    sim.Rollout(seq);
    FAIL() << "expected SimulationError";
  } catch (const SimulationError& e) {
    EXPECT_NE(std::string(e.what()).find("MuJoCo warning"), std::string::npos) << e.what();
    EXPECT_EQ(e.sequence(), 0);
  }
}

// the message gives the step and the time at which it diverged (MuJoCo's reset after a bad
// acceleration sets mjData::time to 0: the time must not be read from it)
TEST(SimulatorTest, DivergenceNamesItsStepAndTime) {
  ModelPtr model = LoadModel(kModels + "/pendulum.xml");
  model->actuator_ctrllimited[0] = 0;
  Simulator sim(*model, {});
  InitialState x0 = sim.ReferenceState();
  x0.time = 1.5;
  RowMatrix ctrl = RowMatrix::Zero(50, 1);
  ctrl.bottomRows(44).setConstant(1e200);  // from step 6 on
  try {
    sim.Rollout(SequenceInput{x0, ctrl});
    FAIL() << "expected SimulationError";
  } catch (const SimulationError& e) {
    EXPECT_EQ(e.step(), 6);
    EXPECT_NE(std::string(e.what()).find("step 6 (t = 1.512 s)"), std::string::npos) << e.what();
  }
}

// the cancel flag stops a rollout or a Jacobian within one time step per worker (Cancelled), and
// the simulator gives the same results afterwards as one never cancelled
TEST(SimulatorTest, CancelFlagStopsWithinAStepAndLeavesTheSimulatorUsable) {
  ModelPtr model = LoadModel(kModels + "/pendulum.xml");
  SimulatorOptions so;
  so.threads = 2;
  Simulator sim(*model, {test::Spec("joint_damping", "hinge")}, so);
  Simulator fresh(*model, {test::Spec("joint_damping", "hinge")}, so);
  const SequenceInput seq{sim.ReferenceState(), test::Excitation(*model, 400, 1.0, 3)};
  const Trajectory nominal = sim.Rollout(seq);
  JacobianOptions jo;
  jo.mode = JacobianMode::kDirectional;
  std::atomic<bool> cancel{true};
  sim.SetCancelFlag(&cancel);
  for (const JacobianMode mode : {JacobianMode::kDirectional, JacobianMode::kMatrix}) {
    jo.mode = mode;
    sim.ResetStepCount();
    EXPECT_THROW(sim.Jacobians(seq, nominal, jo), Cancelled);
    EXPECT_EQ(sim.StepCount(), 0) << JacobianModeName(mode);  // checked before every step
  }
  EXPECT_THROW(sim.Rollout(seq), Cancelled);
  cancel = false;
  const Trajectory again = sim.Rollout(seq);
  EXPECT_TRUE(again.states == fresh.Rollout(seq).states);
  jo.mode = JacobianMode::kDirectional;
  EXPECT_TRUE(sim.Jacobians(seq, again, jo).DyDp == fresh.Jacobians(seq, again, jo).DyDp);
}

TEST(SimulatorTest, BadShapesAreInvalidArguments) {
  ModelPtr model = LoadModel(kModels + "/pendulum.xml");
  Simulator sim(*model, {});
  SequenceInput seq{sim.ReferenceState(), RowMatrix::Zero(10, 2)};
  EXPECT_THROW(sim.Rollout(seq), std::invalid_argument);
  seq.ctrl = RowMatrix::Zero(10, 1);
  seq.x0.qpos = Eigen::VectorXd::Zero(3);
  EXPECT_THROW(sim.Rollout(seq), std::invalid_argument);
  seq.x0.qpos = Eigen::VectorXd::Zero(1);
  seq.ctrl(3, 0) = std::nan("");
  EXPECT_THROW(sim.Rollout(seq), std::invalid_argument);
}

TEST(SimulatorTest, ParameterWithoutEffectIsAnErrorNotAZeroColumn) {
  // the box held high above the floor never touches it: its contact friction changes nothing
  ModelPtr model = LoadModel(kModels + "/box_floor.xml");
  Simulator sim(*model, {Spec("body_mass", "box"), Spec("geom_friction", "box", 0)});
  SequenceInput seq{sim.ReferenceState(), SineControls(*model, 20, 1.0)};
  seq.x0.qpos[2] = 2.0;
  const Trajectory tr = sim.Rollout(seq);
  for (JacobianMode mode : {JacobianMode::kDirectional, JacobianMode::kMatrix}) {
    JacobianOptions opt;
    opt.mode = mode;
    try {
      sim.Jacobians(seq, tr, opt);
      FAIL() << "expected ParameterError";
    } catch (const ParameterError& e) {
      EXPECT_NE(std::string(e.what()).find("geom_friction:box[0]"), std::string::npos) << e.what();
    }
    opt.zero_column_is_error = false;
    const Sensitivity s = sim.Jacobians(seq, tr, opt);
    EXPECT_TRUE(s.DxDp.col(1).isZero(0));
    EXPECT_FALSE(s.DxDp.col(0).isZero(0));
  }
}

// ---------------------------------------------------------------------------------------------
// MuJoCo errors in workers: an error, then the same results as a fresh simulator

// ten free boxes falling above a floor in an 8 KB arena: free fall fits (1.5 KB of stack), but
// a 3 m margin on one box makes it touch all the others and overflows the stack in the
// collision, and mjd_transitionFD (nx^2 doubles of stack) overflows it at once: both are MuJoCo
// errors (mju_error) inside worker tasks. Each leaves stack marked in the worker's mjData (4.3 KB
// for the collision, measured) until mj_resetData.
std::string FallingBoxesXml() {
  std::string xml =
      "<mujoco><size memory=\"8K\"/><worldbody><geom type=\"plane\" size=\"5 5 .1\"/>";
  for (int i = 0; i < 10; ++i) {
    xml += "<body pos=\"" + std::to_string(0.5 * (i % 5)) + " " + std::to_string(0.5 * (i / 5)) +
           " 1\"><freejoint/><geom type=\"box\" size=\".1 .1 .1\"/></body>";
  }
  return xml + "</worldbody><sensor><framepos objtype=\"xbody\" objname=\"world\"/>" +
         "<framelinvel objtype=\"body\" objname=\"world\"/></sensor></mujoco>";
}

TEST(SimulatorTest, MujocoErrorInAWorkerIsAnExceptionAndTheWorkerIsReset) {
  ModelPtr model = LoadModelFromString(FallingBoxesXml());
  // the margin of the second box (geom 2) and the initial state as columns
  ParameterSpec margin;
  margin.kind = "field";
  margin.field = "geom_margin";
  margin.index = 2;
  const std::vector<ParameterSpec> params = {margin};
  Simulator sim(*model, params), fresh(*model, params);
  SequenceInput seq{sim.ReferenceState(), RowMatrix::Zero(20, 0)};
  const Trajectory nominal = sim.Rollout(seq), fresh_nominal = fresh.Rollout(seq);
  ASSERT_EQ(nominal.ncon[19], 0) << "the boxes must still be in the air";

  // failing calls, five times each (a leftover stack mark would add up): a 3 m margin step in a
  // directional column task, and mjd_transitionFD in the time-step tasks of matrix mode
  JacobianOptions failing;
  failing.parameter_steps = {3.0};
  failing.zero_column_is_error = false;
  for (JacobianMode mode : {JacobianMode::kDirectional, JacobianMode::kMatrix}) {
    failing.mode = mode;
    const std::string where =
        mode == JacobianMode::kMatrix ? "at mjd_transitionFD" : "at mj_instantiateContact";
    for (int attempt = 0; attempt < 5; ++attempt) {
      try {
        sim.Jacobians(seq, nominal, failing);
        ADD_FAILURE() << "expected MujocoError, " << JacobianModeName(mode);
      } catch (const MujocoError& e) {
        // MuJoCo's message, whole
        const std::string what = e.what();
        EXPECT_EQ(
            what.rfind("MuJoCo error: mj_stackAlloc: out of memory, stack overflow " + where, 0), 0)
            << what;
        EXPECT_NE(what.find("increase <size memory"), std::string::npos) << what;
      }
    }
  }

  // the same simulator gives bit for bit what a fresh one gives: Jacobians first (a rollout
  // resets the data of its worker anyway), then a rollout
  for (JacobianMode mode : {JacobianMode::kDirectional, JacobianMode::kWholeRollout}) {
    JacobianOptions opt;
    opt.mode = mode;
    opt.initial_state = true;
    opt.zero_column_is_error = false;
    const Sensitivity a = sim.Jacobians(seq, nominal, opt);
    const Sensitivity b = fresh.Jacobians(seq, fresh_nominal, opt);
    EXPECT_TRUE((a.DxDp.array() == b.DxDp.array()).all()) << JacobianModeName(mode);
    EXPECT_TRUE((a.DyDp.array() == b.DyDp.array()).all()) << JacobianModeName(mode);
    EXPECT_GT(a.DxDp.cwiseAbs().maxCoeff(), 0.5) << "the initial-state columns are not zero";
  }
  const Trajectory a = sim.Rollout(seq);
  EXPECT_TRUE((a.states.array() == fresh_nominal.states.array()).all());
  EXPECT_TRUE((a.sensors.array() == fresh_nominal.sensors.array()).all());
}

TEST(SimulatorTest, MujocoErrorInSetParametersKeepsThePreviousValues) {
  // a zero mass on a body that only slides: mj_setConst stops with a MuJoCo error
  ModelPtr model = LoadModel(kModels + "/spring_mass.xml");
  const std::vector<ParameterSpec> params = {Spec("body_mass", "mass")};
  Simulator sim(*model, params), fresh(*model, params);
  Eigen::VectorXd value(1);
  value << 1.7;
  sim.SetParameters(value);
  fresh.SetParameters(value);
  value << 0.0;
  try {
    sim.SetParameters(value);
    FAIL() << "expected MujocoError";
  } catch (const MujocoError& e) {
    EXPECT_NE(std::string(e.what()).find("has 0 mass"), std::string::npos) << e.what();
  }
  // the model is the one of the last successful call, derived constants included
  EXPECT_EQ(sim.GetParameters()[0], 1.7);
  SequenceInput seq{sim.ReferenceState(), SineControls(*model, 200, 2.0)};
  const Trajectory a = sim.Rollout(seq), b = fresh.Rollout(seq);
  EXPECT_TRUE((a.states.array() == b.states.array()).all());
  EXPECT_TRUE((a.sensors.array() == b.sensors.array()).all());
}

// ---------------------------------------------------------------------------------------------
// constraint solvers that are not Newton, and solves that stop at the iteration cap

struct SolverRun {
  SolverStats nominal;
  std::vector<std::string> warnings;
};

// a Jacobian of the box pushed along the floor with the given solver and iteration cap
SolverRun SlidingBox(int solver, int iterations, JacobianMode mode) {
  ModelPtr model = LoadModel(kModels + "/box_floor.xml");
  model->opt.solver = solver;
  model->opt.iterations = iterations;
  Simulator sim(*model, {Spec("geom_friction", "box", 0), Spec("body_mass", "box")});
  SequenceInput seq{sim.ReferenceState(), SineControls(*model, 100, 5.0, 15.0)};
  const Trajectory nominal = sim.Rollout(seq);
  JacobianOptions opt;
  opt.mode = mode;
  return {nominal.solver, sim.Jacobians(seq, nominal, opt).warnings};
}

// the warning that starts with prefix, or "" when there is none
std::string Find(const std::vector<std::string>& warnings, const std::string& prefix) {
  for (const std::string& w : warnings) {
    if (w.rfind(prefix, 0) == 0) return w;
  }
  return "";
}

// the counts of an iteration-cap warning
struct CapCounts {
  int iterations = -1, nominal_capped = -1, nominal = -1, perturbed_capped = -1, perturbed = -1;
};
CapCounts ParseCap(const std::string& w) {
  CapCounts c;
  std::sscanf(w.c_str(),
              "constraint solver stopped at its iteration cap (opt.iterations = %d) in %d of %d "
              "nominal and %d of %d perturbed",
              &c.iterations, &c.nominal_capped, &c.nominal, &c.perturbed_capped, &c.perturbed);
  return c;
}

TEST(SimulatorTest, PgsSolverAndIterationCapAreWarnedWithCounts) {
  const std::string cap = "constraint solver stopped at its iteration cap";
  for (JacobianMode mode : {JacobianMode::kDirectional, JacobianMode::kMatrix}) {
    const char* name = JacobianModeName(mode);
    // PGS capped at 3 iterations: at the core's tolerance (1e-10) most solves stop at the cap
    // (measured: 53 of 73 nominal steps with contacts)
    const SolverRun pgs = SlidingBox(mjSOL_PGS, 3, mode);
    EXPECT_GT(pgs.nominal.solved, 50) << "the box slides in contact with the floor";
    EXPECT_GT(pgs.nominal.capped, pgs.nominal.solved / 2);
    EXPECT_NE(Find(pgs.warnings, "constraint solver is PGS, not Newton"), "") << name;
    const CapCounts c = ParseCap(Find(pgs.warnings, cap));
    EXPECT_EQ(c.iterations, 3) << name;
    EXPECT_EQ(c.nominal_capped, pgs.nominal.capped) << name;
    EXPECT_EQ(c.nominal, pgs.nominal.solved) << name;
    // one perturbed step per parameter (2) and time step, more where both sides were taken
    EXPECT_GE(c.perturbed, 2 * pgs.nominal.solved) << name;
    EXPECT_GT(c.perturbed_capped, c.perturbed / 2) << name;
    EXPECT_LE(c.perturbed_capped, c.perturbed) << name;

    // CG is not Newton either
    EXPECT_NE(Find(SlidingBox(mjSOL_CG, 100, mode).warnings, "constraint solver is CG, not Newton"),
              "")
        << name;
    // Newton with MuJoCo's default cap (100) converges: no solver warning at all
    const SolverRun newton = SlidingBox(mjSOL_NEWTON, 100, mode);
    EXPECT_GT(newton.nominal.solved, 50);
    EXPECT_EQ(newton.nominal.capped, 0);
    EXPECT_EQ(Find(newton.warnings, "constraint solver"), "") << name;
    // Newton capped at one iteration does not converge on the sliding contact: counted
    const SolverRun newton1 = SlidingBox(mjSOL_NEWTON, 1, mode);
    const CapCounts c1 = ParseCap(Find(newton1.warnings, cap));
    EXPECT_EQ(Find(newton1.warnings, "constraint solver is"), "") << name;
    EXPECT_EQ(c1.iterations, 1) << name;
    EXPECT_GT(c1.nominal_capped, 0) << name;
    EXPECT_EQ(c1.nominal_capped, newton1.nominal.capped) << name;
    EXPECT_GT(c1.perturbed_capped, 0) << name;
  }
}

// ---------------------------------------------------------------------------------------------
// a directional column whose perturbation h*|S| passed kSplitGrowth (the warning's 1e-2)
// differences the state and parameter parts apart (core/simulator_internal.h): it stays the
// linearisation of the nominal rollout, which the matrix chain (A_k from mjd_transitionFD)
// computes without any perturbation along S. Truth: the matrix mode's central columns (its forward
// columns agree with them to 4e-6). The double pendulum started upside down (both links at
// pi - 0.3 rad, 6 and -6 rad/s) and driven by a 3 N m sine is chaotic: over 8000 steps (16 s) h*|S|
// reaches 3e4 (h = 1e-6 relative). Measured: one perturbed step from the nominal state moved by
// h*S (no split) is off by 1.05 (forward) and 1.00 (central); split past 1e-2, 6.0e-3 and 6.3e-5.
// Tolerances: 3x those.
TEST(SimulatorTest, DirectionalColumnsPastTheSplitFollowTheMatrixChain) {
  ModelPtr m = LoadModel(kModels + "/double_pendulum.xml");
  Simulator sim(*m, {Spec("body_mass", "link1"), Spec("joint_damping", "hinge2")});
  SequenceInput seq;
  seq.x0 = sim.ReferenceState();
  seq.x0.qpos << M_PI - 0.3, M_PI - 0.3;
  seq.x0.qvel << 6.0, -6.0;
  seq.ctrl = SineControls(sim.model(), 8000, 3.0);
  const Trajectory nominal = sim.Rollout(seq);
  JacobianOptions ref_opt;
  ref_opt.mode = JacobianMode::kMatrix;
  ref_opt.central = true;
  const Sensitivity ref = sim.Jacobians(seq, nominal, ref_opt);
  const double growth = 1e-6 * ref.DxDp.lpNorm<Eigen::Infinity>();
  ASSERT_GT(growth, 1e3) << "the horizon must take h*|S| far past the split";

  for (bool central : {false, true}) {
    JacobianOptions opt;
    opt.mode = JacobianMode::kDirectional;
    opt.central = central;
    const Sensitivity s = sim.Jacobians(seq, nominal, opt);
    const double ey = ColumnScaledError(s.DyDp, ref.DyDp);
    const double ex = ColumnScaledError(s.DxDp, ref.DxDp);
    std::printf("[ measured ] split columns (%s): h*|S| up to %.2e, err(dy)=%.2e err(dx)=%.2e\n",
                central ? "central" : "forward", growth, ey, ex);
    const double tol = central ? 2e-4 : 2e-2;
    EXPECT_LE(ey, tol);
    EXPECT_LE(ex, tol);
    // the warning says where the sensitivity grew and that the parts were differenced apart
    ASSERT_FALSE(s.warnings.empty());
    EXPECT_NE(s.warnings[0].find("differenced apart"), std::string::npos) << s.warnings[0];
  }
}

}  // namespace
}  // namespace mjsysid
