// the evaluation cache on the real pendulum: entries equal the core's own rollouts and Jacobians
// bit for bit, a key seen before costs no simulation step (Simulator::StepCount), a new key is
// simulated, a divergent point is recorded instead of thrown, and a call from a second thread
// aborts (the single-threaded contract of sysid/solve/evaluation_cache.h)
#include "sysid/solve/evaluation_cache.h"

#include <gtest/gtest.h>

#include <cmath>
#include <memory>
#include <string>
#include <thread>
#include <vector>

#include "core/mujoco_env.h"
#include "core/simulator.h"
#include "tests/test_util.h"

namespace mjsysid {
namespace {

const std::string kModels = MJSYSID_MODELS_DIR;

// Two sequences of 200 samples of the pendulum, fitting the hinge damping (log variable):
// segment 0 = samples 0..99 of sequence 0 (x_0 given, continuity to segment 1), segment 1 =
// samples 100..199 of sequence 0 (x_0 a variable), segment 2 = all of sequence 1 (x_0 given).
class EvaluationCacheTest : public ::testing::Test {
 protected:
  EvaluationCacheTest() : model_(LoadModel(kModels + "/pendulum.xml")) {
    params_.push_back(FitParameter("damping", test::Spec("joint_damping", "hinge"), 0.05).Log());
    sim_ = std::make_unique<Simulator>(*model_, std::vector<ParameterSpec>{params_[0].target});
    for (int q = 0; q < 2; ++q) {
      FitSequence sq("seq" + std::to_string(q), "pendulum", InitialState(),
                     test::Excitation(*model_, 200, 2.0, 7 + q), RowMatrix());
      sequences_.push_back(sq);
    }
    segments_ = {{0, 0, 0, 100, -1, 0}, {0, 0, 100, 100, 0, -1}, {1, 0, 0, 200, -1, -1}};
    jacobian_.mode = JacobianMode::kDirectional;
    cache_ =
        std::make_unique<EvaluationCache>(std::vector<EvaluationCache::Model>{{sim_.get(), {0}}},
                                          &params_, &sequences_, &segments_, jacobian_);
    z_ = {std::log(0.08)};
    x0_ = {0.3, 0.0};     // qpos, qvel of segments 0 and 2
    x0_1_ = {0.1, -0.4};  // segment 1's variable x_0
  }

  // the same segment simulated by a separate simulator at the variable z (damping exp z)
  Trajectory Direct(int segment, const std::vector<double>& x0, double z) const {
    Simulator sim(*model_, {params_[0].target});
    sim.SetParameters(Eigen::VectorXd::Constant(1, params_[0].FromVariable(z)));
    return sim.Rollout(Input(segment, x0));
  }
  Sensitivity DirectJacobians(int segment, const std::vector<double>& x0, double z,
                              bool initial_state, bool states) const {
    Simulator sim(*model_, {params_[0].target});
    sim.SetParameters(Eigen::VectorXd::Constant(1, params_[0].FromVariable(z)));
    const SequenceInput in = Input(segment, x0);
    JacobianOptions jo = jacobian_;
    jo.initial_state = initial_state;
    jo.state_jacobians = states;
    jo.zero_column_is_error = false;
    return sim.Jacobians(in, sim.Rollout(in), jo);
  }
  SequenceInput Input(int segment, const std::vector<double>& x0) const {
    const Segment& seg = segments_[segment];
    SequenceInput in;
    in.x0.qpos = Eigen::VectorXd::Constant(1, x0[0]);
    in.x0.qvel = Eigen::VectorXd::Constant(1, x0[1]);
    in.x0.time = seg.k0 * model_->opt.timestep;
    in.ctrl = sequences_[seg.seq].ctrl.middleRows(seg.k0, seg.T);
    return in;
  }

  ModelPtr model_;
  std::vector<FitParameter> params_;
  std::unique_ptr<Simulator> sim_;
  std::vector<FitSequence> sequences_;
  std::vector<Segment> segments_;
  JacobianOptions jacobian_;
  std::unique_ptr<EvaluationCache> cache_;
  std::vector<double> z_, x0_, x0_1_;
};

TEST_F(EvaluationCacheTest, RolloutIsReusedAndJacobiansAddedOnce) {
  const EvaluationCache::Entry& e = cache_->Evaluate(2, z_.data(), x0_.data(), false);
  ASSERT_FALSE(e.failed) << e.error;
  EXPECT_FALSE(e.has_jacobians);
  EXPECT_EQ(sim_->StepCount(), 200);  // one rollout
  EXPECT_TRUE(e.tr.sensors == Direct(2, x0_, z_[0]).sensors);
  // the same key: nothing simulated
  cache_->Evaluate(2, z_.data(), x0_.data(), false);
  EXPECT_EQ(sim_->StepCount(), 200);
  // the Jacobians at the same key: added around the cached rollout, equal to the core's own
  const long long before = sim_->StepCount();
  const EvaluationCache::Entry& j = cache_->Evaluate(2, z_.data(), x0_.data(), true);
  ASSERT_TRUE(j.has_jacobians) << j.error;
  const long long jacobian_steps = sim_->StepCount() - before;
  EXPECT_GT(jacobian_steps, 0);
  EXPECT_EQ(j.s.ncol, 1);
  EXPECT_TRUE(j.s.DyDp == DirectJacobians(2, x0_, z_[0], false, false).DyDp);
  EXPECT_TRUE(j.tr.sensors == Direct(2, x0_, z_[0]).sensors);
  // asked again: nothing simulated
  cache_->Evaluate(2, z_.data(), x0_.data(), true);
  cache_->Evaluate(2, z_.data(), x0_.data(), false);
  EXPECT_EQ(sim_->StepCount(), before + jacobian_steps);
}

TEST_F(EvaluationCacheTest, NewKeyIsSimulated) {
  const RowMatrix first = cache_->Evaluate(2, z_.data(), x0_.data(), false).tr.sensors;
  // another parameter value
  const std::vector<double> z2 = {std::log(0.2)};
  const EvaluationCache::Entry& e = cache_->Evaluate(2, z2.data(), x0_.data(), false);
  EXPECT_EQ(sim_->StepCount(), 400);
  EXPECT_TRUE(e.tr.sensors == Direct(2, x0_, z2[0]).sensors);
  EXPECT_FALSE(e.tr.sensors == first);
  // another initial state
  const std::vector<double> x0b = {0.31, 0.0};
  const EvaluationCache::Entry& f = cache_->Evaluate(2, z2.data(), x0b.data(), false);
  EXPECT_EQ(sim_->StepCount(), 600);
  EXPECT_TRUE(f.tr.sensors == Direct(2, x0b, z2[0]).sensors);
}

// the iterate (an entry with Jacobians) survives trial points: asked for again after two trials
// (the evaluation at the estimate after the solve) it costs no step and is the same; the next
// Jacobians elsewhere drop it (one Jacobian per segment), so it is then simulated anew
TEST_F(EvaluationCacheTest, IterateWithJacobiansSurvivesTrialPoints) {
  const RowMatrix dydp = cache_->Evaluate(2, z_.data(), x0_.data(), true).s.DyDp;
  const std::vector<double> trial1 = {std::log(0.2)}, trial2 = {std::log(0.1)};
  cache_->Evaluate(2, trial1.data(), x0_.data(), false);
  cache_->Evaluate(2, trial2.data(), x0_.data(), false);
  const long long steps = sim_->StepCount();
  const EvaluationCache::Entry& back = cache_->Evaluate(2, z_.data(), x0_.data(), true);
  EXPECT_EQ(sim_->StepCount(), steps);
  ASSERT_TRUE(back.has_jacobians) << back.error;
  EXPECT_TRUE(back.s.DyDp == dydp);
  EXPECT_TRUE(back.tr.sensors == Direct(2, x0_, z_[0]).sensors);
  // Jacobians at a trial point replace the kept iterate: z_ is simulated again (one rollout)
  cache_->Evaluate(2, trial1.data(), x0_.data(), true);
  const long long after_trial = sim_->StepCount();
  cache_->Evaluate(2, trial2.data(), x0_.data(), false);
  cache_->Evaluate(2, z_.data(), x0_.data(), false);
  EXPECT_EQ(sim_->StepCount(), after_trial + 400);
}

// one batch brings every segment to the point, with the Jacobian columns and rows each needs
TEST_F(EvaluationCacheTest, PrefetchThenEvaluateSimulatesNothing) {
  const std::vector<const double*> x0 = {x0_.data(), x0_1_.data(), x0_.data()};
  cache_->Prefetch(z_.data(), x0, true);
  const long long steps = sim_->StepCount();
  const int nx = 2;
  const EvaluationCache::Entry& s0 = cache_->Evaluate(0, z_.data(), x0_.data(), true);
  ASSERT_TRUE(s0.has_jacobians) << s0.error;
  EXPECT_EQ(s0.s.ncol, 1);                      // x_0 given: parameter column only
  EXPECT_EQ(s0.s.DxDp.rows(), (100 + 1) * nx);  // continuity: state rows
  EXPECT_TRUE(s0.s.DxDp == DirectJacobians(0, x0_, z_[0], false, true).DxDp);
  const EvaluationCache::Entry& s1 = cache_->Evaluate(1, z_.data(), x0_1_.data(), true);
  ASSERT_TRUE(s1.has_jacobians) << s1.error;
  EXPECT_EQ(s1.s.ncol, 1 + nx);  // x_0 a variable: its tangent columns
  EXPECT_TRUE(s1.tr.states == Direct(1, x0_1_, z_[0]).states);  // from sample 100, at its time
  EXPECT_TRUE(s1.s.DyDp == DirectJacobians(1, x0_1_, z_[0], true, false).DyDp);
  const EvaluationCache::Entry& s2 = cache_->Evaluate(2, z_.data(), x0_.data(), true);
  ASSERT_TRUE(s2.has_jacobians) << s2.error;
  EXPECT_EQ(sim_->StepCount(), steps);
  // the same point again: every key unchanged, nothing simulated
  cache_->Prefetch(z_.data(), x0, true);
  EXPECT_EQ(sim_->StepCount(), steps);
}

TEST_F(EvaluationCacheTest, SeededEntryIsUsed) {
  const Trajectory tr = Direct(2, x0_, z_[0]);
  cache_->Seed(2, z_.data(), x0_.data(), tr, DirectJacobians(2, x0_, z_[0], false, true));
  const EvaluationCache::Entry& e = cache_->Evaluate(2, z_.data(), x0_.data(), true);
  EXPECT_TRUE(e.has_jacobians);
  EXPECT_EQ(sim_->StepCount(), 0);
  EXPECT_TRUE(e.tr.sensors == tr.sensors);
}

// a seeded entry keeps the state rows (DxDp) only where a residual reads them: segment 2 (single
// shooting, no fitted states) drops them and keeps DyDp bit for bit; segment 0 (continuity) keeps
// both
TEST_F(EvaluationCacheTest, SeededEntryKeepsStateRowsOnlyWhereRead) {
  const Sensitivity s2 = DirectJacobians(2, x0_, z_[0], false, true);
  ASSERT_EQ(s2.DxDp.rows(), 201 * 2);
  cache_->Seed(2, z_.data(), x0_.data(), Direct(2, x0_, z_[0]), s2);
  const EvaluationCache::Entry& e2 = cache_->Evaluate(2, z_.data(), x0_.data(), true);
  EXPECT_TRUE(e2.has_jacobians);
  EXPECT_EQ(e2.s.DxDp.size(), 0);
  EXPECT_TRUE(e2.s.DyDp == s2.DyDp);

  const Sensitivity s0 = DirectJacobians(0, x0_, z_[0], false, true);
  cache_->Seed(0, z_.data(), x0_.data(), Direct(0, x0_, z_[0]), s0);
  const EvaluationCache::Entry& e0 = cache_->Evaluate(0, z_.data(), x0_.data(), true);
  EXPECT_TRUE(e0.s.DxDp == s0.DxDp);
  EXPECT_TRUE(e0.s.DyDp == s0.DyDp);
  EXPECT_EQ(sim_->StepCount(), 0);
}

// a divergent point is an entry that failed with the core's message, not an exception
TEST_F(EvaluationCacheTest, DivergenceIsRecorded) {
  const std::vector<double> wild = {0.3, 1e300};
  const EvaluationCache::Entry& e = cache_->Evaluate(2, z_.data(), wild.data(), true);
  EXPECT_TRUE(e.failed);
  EXPECT_FALSE(e.has_jacobians);
  EXPECT_FALSE(e.error.empty());
  // a good point afterwards is simulated normally
  const EvaluationCache::Entry& g = cache_->Evaluate(2, z_.data(), x0_.data(), false);
  EXPECT_FALSE(g.failed) << g.error;
  EXPECT_TRUE(g.tr.sensors == Direct(2, x0_, z_[0]).sensors);
}

TEST_F(EvaluationCacheTest, CallFromAnotherThreadAborts) {
  GTEST_FLAG_SET(death_test_style, "threadsafe");
  cache_->Evaluate(2, z_.data(), x0_.data(), false);  // fine on the constructing thread
  EXPECT_DEATH(
      {
        std::thread other([&] { cache_->Evaluate(2, z_.data(), x0_.data(), false); });
        other.join();
      },
      "EvaluationCache::Evaluate called from a thread other than the one that built the cache");
  EXPECT_DEATH(
      {
        std::thread other([&] {
          cache_->Prefetch(z_.data(), {x0_.data(), x0_1_.data(), x0_.data()}, false);
        });
        other.join();
      },
      "EvaluationCache::Prefetch called from a thread");
}

}  // namespace
}  // namespace mjsysid
