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

// the four parts of what a step reads (physics, controls, step state, inputs) are exactly the
// full state, with no element twice, on models with and without activations and history buffers
TEST(StateSplitTest, PartsCoverTheFullStateOnce) {
  for (const char* name : {"pendulum.xml", "box_floor.xml", "dcmotor.xml", "servo_delay.xml"}) {
    ModelPtr m = LoadModel(kModels + "/" + name);
    const StateDims dims(*m);
    const unsigned int physics = mjSTATE_QPOS | mjSTATE_QVEL | mjSTATE_ACT;
    const unsigned int step = mjSTATE_TIME | mjSTATE_WARMSTART | dims.step_extra_sig;
    EXPECT_EQ(physics | mjSTATE_CTRL | step | dims.input_sig, kFullStateSig) << name;
    EXPECT_EQ(physics & step, 0u) << name;
    EXPECT_EQ(step & dims.input_sig, 0u) << name;
    EXPECT_EQ((step | dims.input_sig) & mjSTATE_CTRL, 0u) << name;
    EXPECT_EQ(dims.nphys + dims.nu + dims.nstep + dims.ninput, dims.nfull) << name;
  }
}

// restoring physics, step state, controls and inputs into another mjData repeats the step bit for
// bit (contacts, warm start, history buffers of a delayed servo)
TEST(StateSplitTest, RestoredStepRepeatsTheStepBitForBit) {
  for (const char* name : {"box_floor.xml", "servo_delay.xml", "arm7.xml"}) {
    ModelPtr m = LoadModel(kModels + "/" + name);
    const StateDims dims(*m);
    DataPtr a = MakeData(*m), b = MakeData(*m);
    for (int k = 0; k < 300; ++k) {
      SineControls(*m, a.get(), k);
      mj_step(m.get(), a.get());
    }
    SineControls(*m, a.get(), 300);
    std::vector<double> x(dims.nphys), step(dims.nstep), inputs(dims.ninput);
    GetPhysics(*m, *a, x.data());
    GetStepState(*m, dims, *a, step.data());
    if (dims.ninput) mj_getState(m.get(), a.get(), inputs.data(), dims.input_sig);
    // b: another history, then the restore
    for (int k = 0; k < 7; ++k) mj_step(m.get(), b.get());
    if (dims.ninput) mj_setState(m.get(), b.get(), inputs.data(), dims.input_sig);
    SetPhysics(*m, b.get(), x.data());
    SetStepState(*m, dims, b.get(), step.data());
    mju_copy(b->ctrl, a->ctrl, dims.nu);
    mj_step(m.get(), a.get());
    mj_step(m.get(), b.get());
    for (int i = 0; i < m->nq; ++i) ASSERT_EQ(a->qpos[i], b->qpos[i]) << name << " " << i;
    for (int i = 0; i < m->nv; ++i) ASSERT_EQ(a->qvel[i], b->qvel[i]) << name << " " << i;
    for (int i = 0; i < m->na; ++i) ASSERT_EQ(a->act[i], b->act[i]) << name << " " << i;
    for (int i = 0; i < m->nsensordata; ++i) {
      ASSERT_EQ(a->sensordata[i], b->sensordata[i]) << name << " " << i;
    }
  }
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

// Without ball and free joints TangentPerturb and TangentDifference do the position arithmetic
// inline instead of calling mj_integratePos / mj_differentiatePos: the same bits, on hinges and
// slides with positions and steps of many magnitudes (truth: MuJoCo's functions on the same
// inputs; tolerance: none). The ball-joint model takes MuJoCo's path and is compared too.
TEST(TangentTest, InlinePositionMapsEqualMujocosBitForBit) {
  for (const char* name : {"cartpole.xml", "arm7.xml", "double_pendulum.xml", "spring_mass.xml",
                           "ball_pendulum.xml"}) {
    ModelPtr m = LoadModel(kModels + "/" + name);
    DataPtr d = MakeData(*m);
    const StateDims dims(*m);
    std::vector<double> x1(dims.nphys), x2(dims.nphys), dx(dims.nx), got(dims.nx);
    std::vector<double> qpos(dims.nq), qvel(dims.nv);
    for (int trial = 0; trial < 200; ++trial) {
      // a state and a tangent direction of varied magnitudes (quaternions stay as qpos0 has them)
      mju_copy(d->qpos, m->qpos0, dims.nq);
      if (dims.nq == dims.nv) {
        for (int i = 0; i < dims.nq; ++i) d->qpos[i] = std::sin(0.37 * trial + i) * (1 + trial);
      }
      for (int i = 0; i < dims.nv; ++i) d->qvel[i] = std::cos(0.11 * trial * (i + 1));
      for (int i = 0; i < dims.na; ++i) d->act[i] = 0.5 * std::sin(trial + i);
      for (int i = 0; i < dims.nx; ++i) dx[i] = std::sin(1.0 + i + 0.7 * trial) * (trial % 7 + 1);
      const double h = std::pow(10.0, -(trial % 9)) * (1 + 0.01 * trial);
      GetPhysics(*m, *d, x1.data());
      // perturb: qpos as mj_integratePos moves it
      mju_copy(qpos.data(), d->qpos, dims.nq);
      mj_integratePos(m.get(), qpos.data(), dx.data(), h);
      TangentPerturb(*m, d.get(), dx.data(), h);
      for (int i = 0; i < dims.nq; ++i) ASSERT_EQ(d->qpos[i], qpos[i]) << name << " " << i;
      // difference: positions as mj_differentiatePos with dt = 1 / inv_scale
      GetPhysics(*m, *d, x2.data());
      TangentDifference(*m, x1.data(), x2.data(), 1.0 / h, got.data());
      mj_differentiatePos(m.get(), qvel.data(), 1.0 / (1.0 / h), x1.data(), x2.data());
      for (int i = 0; i < dims.nv; ++i) ASSERT_EQ(got[i], qvel[i]) << name << " " << i;
    }
  }
}

}  // namespace
}  // namespace mjsysid
