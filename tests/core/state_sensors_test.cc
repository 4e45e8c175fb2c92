// Sensors copied from the state (core/state_sensors.h): which models get a complete plan, and that
// a Simulator writing them from the state (skipping MuJoCo's sensor stage) produces the same
// rollouts and Jacobians, bit for bit, as one running the sensor stage. Exact equality is the
// claim: the copies must be what MuJoCo writes, cutoff included.
#include "core/state_sensors.h"

#include <gtest/gtest.h>

#include <string>
#include <vector>

#include "core/mujoco_env.h"
#include "core/simulator.h"
#include "tests/test_util.h"

namespace mjsysid {
namespace {

const std::string kModels = MJSYSID_MODELS_DIR;

// a slider carrying a hinged pole, encoders on both joints; the pole's rate sensor has a cutoff
// of 2 rad/s, which the excitation below exceeds (the clamp is exercised)
constexpr char kEncodersXml[] = R"(
<mujoco>
  <option timestep="0.002"/>
  <worldbody>
    <body name="cart">
      <joint name="slider" type="slide" axis="1 0 0" damping="0.2"/>
      <geom type="box" size="0.1 0.05 0.05" mass="1"/>
      <body name="pole">
        <joint name="hinge" type="hinge" axis="0 1 0" damping="0.05"/>
        <geom type="capsule" fromto="0 0 0 0 0 0.5" size="0.02" mass="0.2"/>
      </body>
    </body>
  </worldbody>
  <actuator><motor name="push" joint="slider" ctrlrange="-10 10"/></actuator>
  <sensor>
    <jointvel name="pole_rate" joint="hinge" cutoff="2"/>
    <jointpos name="cart_x" joint="slider"/>
    <jointpos name="pole_angle" joint="hinge"/>
    <jointvel name="cart_v" joint="slider"/>
  </sensor>
</mujoco>)";

ModelPtr WithSensors(const std::string& sensors) {
  std::string xml = kEncodersXml;
  const size_t a = xml.find("<sensor>"), b = xml.find("</sensor>") + 9;
  return LoadModelFromString(xml.substr(0, a) + sensors + xml.substr(b));
}

TEST(StateSensorsTest, EncodersOnlyGiveACompletePlan) {
  ModelPtr m = LoadModelFromString(kEncodersXml);
  const StateSensorPlan plan = PlanStateSensors(*m);
  ASSERT_TRUE(plan.complete);
  ASSERT_EQ(plan.copies.size(), 4u);
  EXPECT_EQ(plan.copies[0].adr, 0);
  EXPECT_EQ(plan.copies[0].qvel, 1);  // the hinge's dof
  EXPECT_EQ(plan.copies[0].qpos, -1);
  EXPECT_EQ(plan.copies[0].cutoff, 2.0);
  EXPECT_EQ(plan.copies[1].qpos, 0);
  EXPECT_EQ(plan.copies[1].cutoff, 0.0);
  // the shipped arm: 14 encoders
  ModelPtr arm = LoadModel(kModels + "/arm7.xml");
  const StateSensorPlan arm_plan = PlanStateSensors(*arm);
  EXPECT_TRUE(arm_plan.complete);
  EXPECT_EQ(arm_plan.copies.size(), 14u);
}

TEST(StateSensorsTest, AnyOtherSensorOrFeatureLeavesThePlanIncomplete) {
  // another sensor type beside the encoders
  ModelPtr frame = WithSensors(
      "<sensor><jointpos joint=\"hinge\"/><framepos objtype=\"body\" objname=\"pole\"/></sensor>");
  EXPECT_FALSE(PlanStateSensors(*frame).complete);
  EXPECT_TRUE(PlanStateSensors(*frame).copies.empty());
  // a delayed encoder: its value comes from the history buffer
  ModelPtr delayed =
      WithSensors("<sensor><jointpos joint=\"hinge\" delay=\"0.004\" nsample=\"4\"/></sensor>");
  EXPECT_GT(delayed->nhistory, 0);
  EXPECT_FALSE(PlanStateSensors(*delayed).complete);
  // no sensors: nothing to copy
  ModelPtr none = WithSensors("");
  EXPECT_FALSE(PlanStateSensors(*none).complete);
  // sleeping enabled: MuJoCo may leave a sleeping sensor's old value
  ModelPtr sleep = LoadModelFromString(kEncodersXml);
  sleep->opt.enableflags |= mjENBL_SLEEP;
  EXPECT_FALSE(PlanStateSensors(*sleep).complete);
}

// rollouts and Jacobians (mode, with the initial-state columns) of two simulators of m, one
// copying the encoders and one running the sensor stage, compared bit for bit
void ExpectSameAsSensorStage(const mjModel& m, const std::vector<ParameterSpec>& specs,
                             const RowMatrix& ctrl, JacobianMode mode, int threads) {
  SimulatorOptions copy, stage;
  copy.threads = stage.threads = threads;
  stage.copy_state_sensors = false;
  Simulator a(m, specs, copy), b(m, specs, stage);
  const SequenceInput in{a.ReferenceState(), ctrl};
  JacobianOptions jo;
  jo.mode = mode;
  jo.initial_state = true;
  test::ExpectSameSimulation(a, b, in, jo);
}

TEST(StateSensorsTest, CopiesEqualTheSensorStageBitForBit) {
  ModelPtr m = LoadModelFromString(kEncodersXml);
  const RowMatrix u = test::Excitation(*m, 700, 8.0, 5);
  // the clamp is active on some samples of the nominal rollout
  Simulator probe(*m, {});
  const Trajectory tr = probe.Rollout({probe.ReferenceState(), u});
  int clamped = 0;
  for (int k = 0; k < tr.T; ++k) clamped += std::abs(tr.sensors(k, 0)) == 2.0;
  EXPECT_GT(clamped, 0);
  const std::vector<ParameterSpec> specs = {test::Spec("joint_damping", "hinge"),
                                            test::Spec("body_mass", "pole"),
                                            test::Spec("joint_damping", "slider")};
  for (JacobianMode mode : {JacobianMode::kDirectional, JacobianMode::kMatrix}) {
    for (int threads : {1, 2}) ExpectSameAsSensorStage(*m, specs, u, mode, threads);
  }
  // the shipped arm (position servos, friction loss), a short excitation
  ModelPtr arm = LoadModel(kModels + "/arm7.xml");
  const RowMatrix ua = test::Excitation(*arm, 300, 1.0, 6);
  ExpectSameAsSensorStage(*arm,
                          {test::Spec("joint_frictionloss", "j1"), test::Spec("body_mass", "link3"),
                           test::Spec("joint_armature", "j5")},
                          ua, JacobianMode::kDirectional, 2);
}

}  // namespace
}  // namespace mjsysid
