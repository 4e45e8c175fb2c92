// Rollouts in pieces (core/simulator.h Rollout; core/simulator_internal.h RolloutPieces): when a
// batch has more sequences than workers and they do not divide evenly, each rollout runs as
// consecutive pieces that continue from the recorded state. The trajectories must be those of one
// piece bit for bit on every kind of state a step reads (contacts and free joints, activations,
// history buffers of delays and sensors), failures and cancellation must behave as in a whole
// rollout, and the task model must see the shorter makespan.
#include <gtest/gtest.h>

#include <atomic>
#include <cmath>
#include <string>
#include <vector>

#include "core/mujoco_env.h"
#include "core/simulator.h"
#include "core/simulator_internal.h"
#include "tests/test_util.h"

namespace mjsysid {
namespace {

const std::string kModels = MJSYSID_MODELS_DIR;

// n sequences of multi-sine controls (test::Excitation), T = T0, T0 + 60, ... steps, from the
// reference state with a velocity kick per sequence (so that later pieces start from moving states)
std::vector<SequenceInput> Sequences(const Simulator& sim, int n, int T0, double amplitude) {
  std::vector<SequenceInput> seqs(n);
  for (int s = 0; s < n; ++s) {
    seqs[s].x0 = sim.ReferenceState();
    seqs[s].x0.qvel.setConstant(0.1 * (s + 1));
    seqs[s].ctrl = test::Excitation(sim.model(), T0 + 60 * s, amplitude, 7 + s);
  }
  return seqs;
}

void ExpectSameTrajectory(const Trajectory& a, const Trajectory& b, const std::string& where) {
  EXPECT_EQ(a.T, b.T) << where;
  EXPECT_TRUE(a.states == b.states) << where;
  EXPECT_TRUE(a.sensors == b.sensors) << where;
  EXPECT_TRUE(a.step == b.step) << where;
  EXPECT_TRUE(a.inputs == b.inputs) << where;
  EXPECT_TRUE(a.ncon == b.ncon) << where;
  EXPECT_EQ(a.solver.solved, b.solver.solved) << where;
  EXPECT_EQ(a.solver.capped, b.solver.capped) << where;
  EXPECT_EQ(a.solver.row_changes, b.solver.row_changes) << where;
  EXPECT_EQ(a.solver.friction_changes, b.solver.friction_changes) << where;
}

TEST(RolloutPiecesTest, PiecesOnlyWhereTheLastRoundWouldLeaveWorkersIdle) {
  ModelPtr model = LoadModel(kModels + "/pendulum.xml");
  for (int threads : {1, 2, 3, 4}) {
    SimulatorOptions so;
    so.threads = threads;
    Simulator sim(*model, {}, so);
    for (int n = 1; n <= 9; ++n) {
      // q = W / gcd(n, W) for n > W not a multiple of W
      int expected = 1;
      if (n > threads && n % threads != 0) {
        int g = threads, r = n;
        while (r) {
          const int t = g % r;
          g = r;
          r = t;
        }
        expected = threads / g;
      }
      EXPECT_EQ(internal::RolloutPieces(n, sim.threads(), 10000), expected)
          << threads << " threads, " << n;
      // too short for pieces of kMinPieceSteps
      EXPECT_EQ(internal::RolloutPieces(n, sim.threads(), internal::kMinPieceSteps * expected - 1),
                1)
          << threads << " threads, " << n;
    }
  }
  SimulatorOptions so;
  so.threads = 2;
  Simulator two(*model, {}, so);
  EXPECT_EQ(internal::RolloutPieces(3, two.threads(), 1000), 2);
  EXPECT_EQ(internal::RolloutPieces(2, two.threads(), 1000), 1);
  so.threads = 4;
  Simulator four(*model, {}, so);
  EXPECT_EQ(internal::RolloutPieces(6, four.threads(), 1000), 2);  // 12 pieces: 3 full rounds
  EXPECT_EQ(internal::RolloutPieces(5, four.threads(), 1000), 4);  // 20 pieces: 5 full rounds
}

// Every model kind of state: 3 sequences on 2 workers (2 pieces each) and 5 on 3 (3 pieces each)
// give the trajectories of 1 worker (no pieces) bit for bit
TEST(RolloutPiecesTest, PiecesGiveTheWholeRolloutBitForBit) {
  const std::vector<std::pair<std::string, double>> models = {
      {"box_floor.xml", 25.0},     // free joint, contacts that come and go (a 25 N push)
      {"robust/hopper.xml", 1.0},  // planar legged robot in contact
      {"humanoid.xml", 1.0},       // many contacts, ball joints
      {"dcmotor_lugre.xml", 1.0},  // activations (2)
      {"kinds_bench.xml", 1.0},    // activations (6), many actuator kinds
      {"servo_arm7.xml", 1.0},     // actuator delays: history buffers
      {"sensor_delay3.xml", 1.0},  // sensor delays: history buffers
  };
  for (const auto& [name, amplitude] : models) {
    ModelPtr model = LoadModel(kModels + "/" + name);
    Simulator serial(*model, {});
    for (const auto& [threads, n] : std::vector<std::pair<int, int>>{{2, 3}, {3, 5}}) {
      const std::vector<SequenceInput> seqs = Sequences(serial, n, 200, amplitude);
      std::vector<Trajectory> expected;
      serial.Rollout(seqs, &expected);
      SimulatorOptions so;
      so.threads = threads;
      Simulator sim(*model, {}, so);
      ASSERT_EQ(internal::RolloutPieces(n, sim.threads(), 200), threads)
          << name;  // 2 or 3 pieces of >= 66 steps
      std::vector<Trajectory> got;
      sim.Rollout(seqs, &got);
      ASSERT_EQ(got.size(), expected.size());
      for (int s = 0; s < n; ++s) {
        ExpectSameTrajectory(
            got[s], expected[s],
            name + ", " + std::to_string(threads) + " threads, seq " + std::to_string(s));
      }
      // every step counted once: pieces restore, they do not step twice
      long long steps = 0;
      for (const SequenceInput& q : seqs) steps += q.ctrl.rows();
      sim.ResetStepCount();
      sim.Rollout(seqs, &got);
      EXPECT_EQ(sim.StepCount(), steps) << name;
    }
  }
}

// The task model sees the pieces: 3 rollouts of T steps on 2 workers end after 1.5 T steps (2 T
// as whole rollouts)
TEST(RolloutPiecesTest, ThreeRolloutsOnTwoWorkersTakeOneAndAHalfRolloutTimes) {
  ModelPtr model = LoadModel(kModels + "/cartpole.xml");
  SimulatorOptions so;
  so.threads = 2;
  Simulator sim(*model, {}, so);
  std::vector<SequenceInput> seqs = Sequences(sim, 3, 400, 0.5);
  for (SequenceInput& s : seqs) s.ctrl.conservativeResize(400, Eigen::NoChange);  // equal T
  std::vector<Trajectory> tr;
  sim.ResetStepCount();
  sim.Rollout(seqs, &tr);
  const PoolLoad& load = sim.ParallelLoad();
  EXPECT_EQ(load.batches, 1);
  EXPECT_EQ(load.work, 3 * 400);
  EXPECT_EQ(load.span[1], 3 * 400);
  EXPECT_EQ(load.span[2], 600);  // pieces of 200: a1 a2 | a3 b1 | b2 b3
}

// A rollout that diverges in its second piece is the SimulationError of a whole rollout (its step
// named), one that diverges in its first piece stops its later piece too; afterwards the simulator
// gives the results of a fresh one
TEST(RolloutPiecesTest, DivergenceInAnyPieceIsTheWholeRolloutsError) {
  ModelPtr model = LoadModel(kModels + "/pendulum.xml");
  model->actuator_ctrllimited[0] = 0;
  SimulatorOptions so;
  so.threads = 2;
  Simulator sim(*model, {}, so);
  for (int bad_step : {250, 40}) {
    std::vector<SequenceInput> seqs = Sequences(sim, 3, 300, 0.5);
    for (SequenceInput& s : seqs) s.ctrl.conservativeResize(300, Eigen::NoChange);
    seqs[1].ctrl.bottomRows(300 - bad_step).setConstant(1e200);
    std::vector<Trajectory> tr;
    try {
      sim.Rollout(seqs, &tr);
      FAIL() << "expected SimulationError at step " << bad_step;
    } catch (const SimulationError& e) {
      EXPECT_EQ(e.sequence(), 1) << e.what();
      EXPECT_EQ(e.step(), bad_step) << e.what();
    }
    const std::vector<SequenceInput> good = Sequences(sim, 3, 300, 0.5);
    sim.Rollout(good, &tr);
    Simulator fresh(*model, {});
    std::vector<Trajectory> expected;
    fresh.Rollout(good, &expected);
    for (int s = 0; s < 3; ++s) {
      ExpectSameTrajectory(tr[s], expected[s], "after step " + std::to_string(bad_step));
    }
  }
}

// A cancel flag stops pieces as it stops whole rollouts
TEST(RolloutPiecesTest, CancelStopsThePiecesAndLeavesTheSimulatorUsable) {
  ModelPtr model = LoadModel(kModels + "/cartpole.xml");
  SimulatorOptions so;
  so.threads = 2;
  Simulator sim(*model, {}, so);
  const std::vector<SequenceInput> seqs = Sequences(sim, 3, 300, 0.5);
  std::atomic<bool> cancel{true};
  sim.SetCancelFlag(&cancel);
  std::vector<Trajectory> tr;
  EXPECT_THROW(sim.Rollout(seqs, &tr), Cancelled);
  cancel = false;
  sim.Rollout(seqs, &tr);
  Simulator fresh(*model, {});
  std::vector<Trajectory> expected;
  fresh.Rollout(seqs, &expected);
  for (int s = 0; s < 3; ++s) ExpectSameTrajectory(tr[s], expected[s], "after cancel");
}

}  // namespace
}  // namespace mjsysid
