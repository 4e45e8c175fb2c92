// SolverStats::row_changes and friction_changes (core/solver_stats.h) on real rollouts: what tells
// the interval check (sysid/assess/interval_check.h) that a rollout's constraint forces switched
// branch. Truth by construction: a ball dropped on the floor (contact rows come at the impact), a
// hinge swinging into its limit (a limit row comes), a hinge with friction loss under a slow sine
// torque (its friction row sticks and slips, no row comes or goes), the same hinge without friction
// loss and limits (no row at all).
#include "core/solver_stats.h"

#include <gtest/gtest.h>

#include <string>

#include "core/mujoco_env.h"
#include "core/simulator.h"
#include "tests/test_util.h"

namespace mjsysid {
namespace {

// a hinge pendulum with one motor; {JOINT} completes the joint's attributes
const char* kHinge = R"(
<mujoco>
  <option timestep="0.002"/>
  <worldbody>
    <body pos="0 0 1">
      <joint name="hinge" type="hinge" axis="0 1 0" damping="0.05" {JOINT}/>
      <geom type="capsule" fromto="0 0 0 0.3 0 0" size="0.03" mass="1" contype="0"
            conaffinity="0"/>
    </body>
  </worldbody>
  <actuator><motor joint="hinge" gear="1"/></actuator>
</mujoco>)";

// the rollout of T steps from qpos qpos0 under the torque amplitude * sin(2 pi t / 2 s)
Trajectory Roll(const std::string& xml, double qpos0, double amplitude, int T) {
  const ModelPtr m = LoadModelFromString(xml);
  Simulator sim(*m, {});
  SequenceInput in;
  in.x0.qpos = Eigen::VectorXd::Constant(m->nq, qpos0);
  in.ctrl = RowMatrix::Zero(T, m->nu);
  for (int k = 0; k < T && m->nu > 0; ++k) {
    in.ctrl(k, 0) = amplitude * std::sin(2 * M_PI * k * m->opt.timestep / 2.0);
  }
  return sim.Rollout(in);
}

TEST(SolverStatsTest, NoConstraintRowsNoChanges) {
  const Trajectory tr = Roll(test::FillTemplate(kHinge, {{"JOINT", ""}}), 0.5, 1.0, 1000);
  EXPECT_EQ(tr.solver.solved, 0);
  EXPECT_EQ(tr.solver.row_changes, 0);
  EXPECT_EQ(tr.solver.friction_changes, 0);
}

TEST(SolverStatsTest, FrictionLossSticksAndSlipsWithoutRowChanges) {
  // friction loss 0.5 N m against a torque of amplitude 2 N m: it slips while the torque is large
  // and sticks around the torque's zero crossings (0.5 s apart of each 1 s)
  const Trajectory tr =
      Roll(test::FillTemplate(kHinge, {{"JOINT", "frictionloss=\"0.5\""}}), 0.0, 2.0, 2000);
  EXPECT_EQ(tr.solver.solved, 2000);  // the friction row is there in every step
  EXPECT_EQ(tr.solver.row_changes, 0);
  EXPECT_GE(tr.solver.friction_changes, 2);
}

TEST(SolverStatsTest, LimitRowComesAndGoes) {
  // from 0.5 rad under gravity alone the pendulum swings through -0.2 rad, below the limit
  const Trajectory tr =
      Roll(test::FillTemplate(kHinge, {{"JOINT", "range=\"-0.2 1\""}}), 0.5, 0.0, 1000);
  EXPECT_GT(tr.solver.solved, 0);
  EXPECT_LT(tr.solver.solved, 1000);
  EXPECT_GE(tr.solver.row_changes, 2);  // the limit row came and went at least once
}

TEST(SolverStatsTest, ContactRowsComeAtTheImpact) {
  const ModelPtr m = LoadModelFromString(R"(
<mujoco>
  <option timestep="0.002"/>
  <worldbody>
    <geom type="plane" size="2 2 0.1"/>
    <body pos="0 0 0.3"><freejoint/><geom type="sphere" size="0.05" mass="0.2"/></body>
  </worldbody>
</mujoco>)");
  Simulator sim(*m, {});
  SequenceInput in;
  in.x0 = sim.ReferenceState();
  in.ctrl = RowMatrix::Zero(500, 0);
  const Trajectory tr = sim.Rollout(in);
  int contact_steps = 0;
  for (int n : tr.ncon) contact_steps += n > 0 ? 1 : 0;
  ASSERT_GT(contact_steps, 0);  // it lands within 1 s (0.25 m fall: 0.23 s)
  EXPECT_GE(tr.solver.row_changes, 1);
}

}  // namespace
}  // namespace mjsysid
