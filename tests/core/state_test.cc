#include "core/state.h"

#include <gtest/gtest.h>

#include <cmath>
#include <string>
#include <vector>

#include "core/mujoco_env.h"

namespace mjsysid {
namespace {

const std::string kModels = MJSYSID_MODELS_DIR;

// controls that excite every actuator differently
void SineControls(const mjModel& m, mjData* d, int k) {
  for (int i = 0; i < m.nu; ++i) d->ctrl[i] = 0.8 * std::sin(0.013 * k * (i + 1) + 0.3 * i);
}

class StepSkipTest : public ::testing::TestWithParam<std::pair<std::string, int>> {};

// StepSkip(mjSTAGE_NONE) makes exactly the calls of mj_step: bit-identical trajectories
TEST_P(StepSkipTest, NoSkipEqualsMjStepBitForBit) {
  ModelPtr m = LoadModel(kModels + "/" + GetParam().first);
  m->opt.integrator = GetParam().second;
  DataPtr a = MakeData(*m), b = MakeData(*m);
  for (int k = 0; k < 500; ++k) {
    SineControls(*m, a.get(), k);
    SineControls(*m, b.get(), k);
    mj_step(m.get(), a.get());
    StepSkip(m.get(), b.get(), mjSTAGE_NONE, false);
  }
  for (int i = 0; i < m->nq; ++i) ASSERT_EQ(a->qpos[i], b->qpos[i]) << i;
  for (int i = 0; i < m->nv; ++i) ASSERT_EQ(a->qvel[i], b->qvel[i]) << i;
  for (int i = 0; i < m->nsensordata; ++i) ASSERT_EQ(a->sensordata[i], b->sensordata[i]) << i;
  EXPECT_EQ(SimulationWarnings(*a), "");
}

INSTANTIATE_TEST_SUITE_P(Models, StepSkipTest,
                         ::testing::Values(std::make_pair("pendulum.xml", mjINT_EULER),
                                           std::make_pair("cartpole.xml", mjINT_IMPLICITFAST),
                                           std::make_pair("box_floor.xml", mjINT_EULER),
                                           std::make_pair("box_floor.xml", mjINT_IMPLICIT),
                                           std::make_pair("ball_pendulum.xml", mjINT_RK4)));

// a MuJoCo error inside StepSkip (here its own check of the integrator) is a MujocoError, and the
// data steps again after mj_resetData
TEST(StepSkipTest, MujocoErrorIsAnExceptionAndDataStepsAfterReset) {
  ModelPtr m = LoadModel(kModels + "/pendulum.xml");
  DataPtr d = MakeData(*m);
  m->opt.integrator = 42;
  try {
    StepSkip(m.get(), d.get(), mjSTAGE_NONE, false);
    FAIL() << "expected MujocoError";
  } catch (const MujocoError& e) {
    EXPECT_EQ(std::string(e.what()), "MuJoCo error: StepSkip: invalid integrator 42");
  }
  m->opt.integrator = mjINT_EULER;
  mj_resetData(m.get(), d.get());
  DataPtr fresh = MakeData(*m);
  StepSkip(m.get(), d.get(), mjSTAGE_NONE, false);
  mj_step(m.get(), fresh.get());
  EXPECT_EQ(d->qpos[0], fresh->qpos[0]);
  EXPECT_EQ(d->qvel[0], fresh->qvel[0]);
}

// skipping the position stage after an unchanged forward pass changes nothing
TEST(StepSkipTest, SkipAfterForwardEqualsFullStep) {
  ModelPtr m = LoadModel(kModels + "/box_floor.xml");
  DataPtr a = MakeData(*m), b = MakeData(*m);
  for (int k = 0; k < 300; ++k) {
    SineControls(*m, a.get(), k);
    mj_step(m.get(), a.get());
  }
  std::vector<double> state(mj_stateSize(m.get(), kFullStateSig));
  mj_getState(m.get(), a.get(), state.data(), kFullStateSig);
  mj_setState(m.get(), b.get(), state.data(), kFullStateSig);
  mj_forward(m.get(), b.get());
  mj_step(m.get(), a.get());
  StepSkip(m.get(), b.get(), mjSTAGE_POS, false);
  for (int i = 0; i < m->nq; ++i) EXPECT_EQ(a->qpos[i], b->qpos[i]) << i;
  for (int i = 0; i < m->nv; ++i) EXPECT_EQ(a->qvel[i], b->qvel[i]) << i;
}

// perturbing along a tangent direction and differencing recovers the direction, on quaternions
TEST(TangentTest, PerturbThenDifferenceRoundTrips) {
  ModelPtr m = LoadModel(kModels + "/box_floor.xml");  // free joint: nq = 7, nv = 6
  DataPtr d = MakeData(*m);
  const StateDims dims(*m);
  ASSERT_EQ(dims.nq, 7);
  ASSERT_EQ(dims.nx, 12);
  // a rotated, moving state
  d->qpos[3] = std::cos(0.4);
  d->qpos[4] = std::sin(0.4) * 0.6;
  d->qpos[5] = std::sin(0.4) * 0.8;
  d->qpos[6] = 0;
  for (int i = 0; i < dims.nv; ++i) d->qvel[i] = 0.1 * (i + 1);
  std::vector<double> x1(dims.nphys), x2(dims.nphys), dx(dims.nx), back(dims.nx);
  GetPhysics(*m, *d, x1.data());
  for (int i = 0; i < dims.nx; ++i) dx[i] = std::sin(1.0 + i);
  const double h = 1e-3;
  TangentPerturb(*m, d.get(), dx.data(), h);
  GetPhysics(*m, *d, x2.data());
  // the quaternion stays unit length
  double norm = 0;
  for (int i = 3; i < 7; ++i) norm += x2[i] * x2[i];
  EXPECT_NEAR(norm, 1.0, 1e-14);
  TangentDifference(*m, x1.data(), x2.data(), 1.0 / h, back.data());
  for (int i = 0; i < dims.nx; ++i) EXPECT_NEAR(back[i], dx[i], 1e-9) << i;
}

}  // namespace
}  // namespace mjsysid
