// every parameter writer against a model compiled from XML with the edited value
#include "core/parameters.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <fstream>
#include <map>
#include <set>
#include <sstream>
#include <string>
#include <utility>
#include <vector>

#include "core/mujoco_env.h"
#include "core/state.h"
#include "tests/core/inertial_by_hand.h"
#include "tests/test_util.h"

namespace mjsysid {
namespace {

// a scene with a hinge link (explicit inertial at the body origin: "same frame"), a ball joint,
// a slider on a "simple" body, a free box sliding on a floor, and four actuators
const char* kTemplate = R"(
<mujoco>
  <option timestep="0.002"/>
  <worldbody>
    <geom name="floor" type="plane" size="5 5 .1" friction="0.1 0.001 0.0001"/>
    <body name="link" pos="0 0 2">
      <joint name="hinge" type="hinge" axis="0 1 0" damping="{damping}"
             frictionloss="{frictionloss}" armature="{armature}" stiffness="{stiffness}"/>
      <inertial pos="{com_x} 0 {com_z}" mass="{mass}" diaginertia="0.03 0.04 0.02"/>
      <geom type="capsule" fromto="0 0 0 0 0 -0.4" size="0.03" contype="0" conaffinity="0"/>
      <body name="tip" pos="0 0 -0.4">
        <joint name="ball" type="ball" damping="{ball_damping}" armature="{ball_armature}"/>
        <inertial pos="0.05 0 -0.2" mass="{tip_mass}" diaginertia="{ix} {iy} {iz}"/>
        <geom type="sphere" size="0.05" contype="0" conaffinity="0"/>
      </body>
    </body>
    <body name="slider" pos="2 0 1">
      <joint name="slide" type="slide" axis="1 0 0" armature="{slide_armature}"/>
      <inertial pos="0 0 0" mass="{slider_mass}" diaginertia="0.01 0.01 0.01"/>
      <geom type="sphere" size="0.05" contype="0" conaffinity="0"/>
    </body>
    <body name="box" pos="0 2 0.1">
      <freejoint name="free"/>
      <geom name="box" type="box" size=".1 .1 .1" mass="1" friction="{box_mu} 0.005 0.0001"/>
      <site name="push"/>
    </body>
  </worldbody>
  <actuator>
    <general name="act" joint="hinge" biastype="affine" gainprm="{gain}" biasprm="0 {bias1} 0" gear="{gear}"/>
    <motor name="slide_motor" joint="slide"/>
    <motor name="box_motor" site="push" gear="1 0 0 0 0 0"/>
    <motor name="twist" joint="ball" gear="0.3 0.2 1"/>
  </actuator>
  <sensor>
    <jointpos joint="hinge"/>
  </sensor>
</mujoco>)";

const std::map<std::string, double> kDefaults = {
    {"damping", 0.2},        {"frictionloss", 0.05},  {"armature", 0.02},   {"stiffness", 1.5},
    {"com_x", 0.0},          {"com_z", 0.0},          {"mass", 1.2},        {"ix", 0.01},
    {"iy", 0.012},           {"iz", 0.005},           {"tip_mass", 0.5},    {"ball_damping", 0.1},
    {"ball_armature", 0.01}, {"slide_armature", 0.0}, {"slider_mass", 2.0}, {"box_mu", 0.6},
    {"gain", 3.0},           {"bias1", -1.0},         {"gear", 1.0}};

// the template with the defaults, some replaced
std::string Xml(const std::map<std::string, double>& overrides) {
  std::map<std::string, std::string> values;
  for (const auto& [key, def] : kDefaults) {
    const auto it = overrides.find(key);
    char buf[64];
    std::snprintf(buf, sizeof(buf), "%.17g", it == overrides.end() ? def : it->second);
    values[key] = buf;
  }
  return test::FillTemplate(kTemplate, values);
}

// 500 steps under sine controls from the reference state: the physics vectors x_1..x_500
std::vector<double> Simulate(const mjModel& m) { return test::SineRollout(m, 500, 0.02); }

struct WriterCase {
  ParameterSpec spec;
  std::string key;  // template key edited in the XML
  double value;     // new value
};

class WriterTest : public ::testing::TestWithParam<WriterCase> {};

TEST_P(WriterTest, InPlaceWriteMatchesCompiledXml) {
  const WriterCase& c = GetParam();
  ModelPtr base = LoadModelFromString(Xml({}));
  ModelPtr edited_xml = LoadModelFromString(Xml({{c.key, c.value}}));

  // write the parameter into a copy of the base model
  ModelPtr written = CopyModel(*base);
  ParameterSet params(*written, {c.spec});
  params.Prepare(written.get());
  DataPtr scratch = MakeData(*written);
  params.Write(written.get(), scratch.get(), &c.value);
  double readback = 0;
  params.Read(*written, &readback);
  EXPECT_EQ(readback, c.value);

  const std::vector<double> traj_base = Simulate(*base);
  const std::vector<double> traj_xml = Simulate(*edited_xml);
  const std::vector<double> traj_written = Simulate(*written);
  // the edit matters (so the comparison can fail) ...
  EXPECT_GT(test::MaxAbsDiff(traj_base, traj_xml), 1e-6) << "edit of " << c.key << " has no effect";
  // ... and the in-place write reproduces the compiled model
  EXPECT_LE(test::MaxAbsDiff(traj_written, traj_xml), 1e-12) << params[0].label();
}

using test::Spec;

INSTANTIATE_TEST_SUITE_P(
    Writers, WriterTest,
    ::testing::Values(
        WriterCase{Spec("body_mass", "tip"), "tip_mass", 0.7},
        WriterCase{Spec("body_mass", "slider"), "slider_mass", 3.1},  // simple body
        WriterCase{Spec("body_inertia", "tip", 0), "ix", 0.015},
        WriterCase{Spec("body_inertia", "tip", 1), "iy", 0.014},
        WriterCase{Spec("body_inertia", "tip", 2), "iz", 0.009},
        WriterCase{Spec("body_com", "link", 0), "com_x", 0.08},  // body in "same frame"
        WriterCase{Spec("body_com", "link", 2), "com_z", -0.1},
        WriterCase{Spec("joint_damping", "hinge"), "damping", 0.55},
        WriterCase{Spec("joint_damping", "ball"), "ball_damping", 0.3},  // 3 dofs
        WriterCase{Spec("joint_frictionloss", "hinge"), "frictionloss", 0.2},
        WriterCase{Spec("joint_armature", "hinge"), "armature", 0.09},
        WriterCase{Spec("joint_armature", "ball"), "ball_armature", 0.05},
        WriterCase{Spec("joint_armature", "slide"), "slide_armature", 0.4},  // simple body
        WriterCase{Spec("joint_stiffness", "hinge"), "stiffness", 4.0},
        WriterCase{Spec("geom_friction", "box", 0), "box_mu", 0.3},  // contact
        WriterCase{Spec("actuator_gain", "act", 0), "gain", 5.0},
        WriterCase{Spec("actuator_bias", "act", 1), "bias1", -2.5},
        WriterCase{Spec("actuator_gear", "act", 0), "gear", 1.8}),
    [](const ::testing::TestParamInfo<WriterCase>& param_info) {
      return param_info.param.spec.kind + "_" + param_info.param.key;
    });

// body_mass_inertia scales the inertia with the mass (uniform density)
TEST(WriterTest, MassWithInertiaMatchesCompiledXml) {
  ModelPtr base = LoadModelFromString(Xml({}));
  const double scale = 0.8 / 0.5;
  ModelPtr edited_xml = LoadModelFromString(
      Xml({{"tip_mass", 0.8}, {"ix", 0.01 * scale}, {"iy", 0.012 * scale}, {"iz", 0.005 * scale}}));
  ModelPtr written = CopyModel(*base);
  ParameterSet params(*written, {Spec("body_mass_inertia", "tip")});
  params.Prepare(written.get());
  DataPtr scratch = MakeData(*written);
  const double value = 0.8;
  params.Write(written.get(), scratch.get(), &value);
  EXPECT_LE(test::MaxAbsDiff(Simulate(*written), Simulate(*edited_xml)), 1e-12);
}

// the generic escape hatch: any mjtNum array of mjModel by name and flat index
TEST(WriterTest, FieldByNameMatchesCompiledXml) {
  ModelPtr base = LoadModelFromString(Xml({}));
  ModelPtr edited_xml = LoadModelFromString(Xml({{"damping", 0.8}}));
  ParameterSpec spec;
  spec.kind = "field";
  spec.field = "dof_damping";
  spec.index = base->jnt_dofadr[mj_name2id(base.get(), mjOBJ_JOINT, "hinge")];
  ModelPtr written = CopyModel(*base);
  ParameterSet params(*written, {spec});
  DataPtr scratch = MakeData(*written);
  const double value = 0.8;
  params.Write(written.get(), scratch.get(), &value);
  EXPECT_EQ(params[0].label(), "field:dof_damping[" + std::to_string(spec.index) + "]");
  EXPECT_LE(test::MaxAbsDiff(Simulate(*written), Simulate(*edited_xml)), 1e-12);
}

// the traps the contract of core/parameters.h works around are real: without mj_setConst a simple
// body ignores its new mass, and the "same frame" flag ignores a new centre of mass
TEST(WriterTest, TrapsAreRealWithoutSetConstAndPrepare) {
  ModelPtr base = LoadModelFromString(Xml({}));
  const int slider = mj_name2id(base.get(), mjOBJ_BODY, "slider");
  const int link = mj_name2id(base.get(), mjOBJ_BODY, "link");
  ASSERT_NE(base->body_simple[slider], 0) << "the slider must be a simple body for this test";
  ASSERT_NE(base->body_sameframe[link], 0) << "the link must be in the same frame for this test";

  ModelPtr raw = CopyModel(*base);
  Parameter::Resolve(*raw, Spec("body_mass", "slider")).WriteRaw(raw.get(), 3.1);
  EXPECT_EQ(test::MaxAbsDiff(Simulate(*raw), Simulate(*base)), 0.0)
      << "MuJoCo no longer ignores a raw mass write on a simple body: update core/parameters.h";

  // a raw centre-of-mass write on a "same frame" body is ignored or rejected by MuJoCo
  ModelPtr com_raw = CopyModel(*base);
  Parameter::Resolve(*com_raw, Spec("body_com", "link", 0)).WriteRaw(com_raw.get(), 0.08);
  const std::vector<double> xml = Simulate(*LoadModelFromString(Xml({{"com_x", 0.08}})));
  bool rejected = false;
  std::vector<double> traj;
  try {
    traj = Simulate(*com_raw);
  } catch (const MujocoError&) {
    rejected = true;
  }
  EXPECT_TRUE(rejected || test::MaxAbsDiff(traj, xml) > 1e-6)
      << "MuJoCo honours a raw body_ipos write on a same-frame body: update core/parameters.h";
}

// ---------------------------------------------------------------------------------------------
// robot-grade kinds: tendons, contact softness and pair friction, servo gains, full inertia

// a position servo (kp, kv) on an arm with a full inertia (and a free roll joint), a pid on its
// elbow (with a tendon spring), a velocity servo on a wheel, a box pushed over the floor and a puck
// in an explicit contact pair with the floor
const char* kRobotTemplate = R"(
<mujoco>
  <option timestep="0.002"/>
  <worldbody>
    <geom name="floor" type="plane" size="5 5 .1"/>
    <body name="arm" pos="0 0 2">
      <joint name="shoulder" type="hinge" axis="0 1 0" damping="0.05"/>
      <joint name="roll" type="hinge" axis="1 0 0" damping="0.05"/>
      <inertial pos="{arm_com}" mass="{arm_mass}" fullinertia="{arm_inertia}"/>
      <geom type="capsule" fromto="0 0 0 0 0 -0.3" size="0.03" contype="0" conaffinity="0"/>
      <body name="forearm" pos="0 0 -0.3">
        <joint name="elbow" type="hinge" axis="0 1 0"/>
        <geom type="capsule" fromto="0 0 0 0.2 0 -0.2" size="0.02" mass="0.3" contype="0"
              conaffinity="0"/>
      </body>
    </body>
    <body name="wheel" pos="-2 0 1">
      <joint name="spin" type="hinge" axis="1 0 0"/>
      <geom type="cylinder" size="0.1 0.02" mass="0.5" contype="0" conaffinity="0"/>
    </body>
    <body name="rotor" pos="-2 1 1">
      <joint name="rotor" type="hinge" axis="1 0 0" damping="0.001"/>
      <geom type="cylinder" size="0.05 0.02" mass="0.3" contype="0" conaffinity="0"/>
    </body>
    <body name="box" pos="0 2 0.1">
      <freejoint/>
      <geom name="box" type="box" size=".1 .1 .1" mass="1" friction="0.6 0.005 0.0001"
            solref="{box_tc} 1" solimp="0.9 {box_dmax} 0.001 0.5 2"/>
      <site name="push"/>
    </body>
    <body name="puck" pos="2 2 0.05">
      <freejoint/>
      <geom name="puck" type="sphere" size="0.05" mass="0.2" contype="0" conaffinity="0"/>
      <site name="puck_push"/>
    </body>
  </worldbody>
  <contact>
    <pair name="puck_floor" geom1="floor" geom2="puck" condim="{pair_condim}"
          friction="{pair_mu} {pair_mu2} 0.005 {pair_roll1} {pair_roll2}" solref="{pair_tc} 1"
          solimp="{pair_dmin} 0.95 0.001 0.5 2"/>
  </contact>
  <tendon>
    <fixed name="elbow_spring" stiffness="{tendon_k}" damping="{tendon_d}"
           frictionloss="{tendon_f}" springlength="{tendon_l}">
      <joint joint="elbow" coef="1"/>
    </fixed>
  </tendon>
  <actuator>
    <position name="shoulder_servo" joint="shoulder" kp="{kp}" kv="{kv}" delay="{delay}"
              nsample="8" interp="linear"/>
    <velocity name="spin_servo" joint="spin" kv="{spin_kv}"/>
    <pid name="elbow_pid" joint="elbow" kp="{pid_kp}" ki="{pid_ki}" kv="{pid_kv}"/>
    <motor name="box_motor" site="push" gear="1 0 0 0 0 0"/>
    <motor name="puck_motor" site="puck_push" gear="0.6 0.8 0 0 0 0"/>
    <dcmotor name="dc" joint="rotor" motorconst="{dc_k}" resistance="{dc_r}" inductance="{dc_l}"
             cogging="{cog_a} 6 {cog_ph}" lugre="{lugre0} 0.3 {lugre2} 0.03 {lugre4}"/>
  </actuator>
  <sensor>
    <jointpos name="elbow_angle" joint="elbow" delay="{sensor_delay}" nsample="5" interp="linear"/>
  </sensor>
</mujoco>)";

const std::map<std::string, std::string> kRobotDefaults = {
    {"arm_com", "0.02 0.01 -0.15"},
    {"arm_mass", "1.1"},
    {"arm_inertia", "0.02 0.025 0.012 0.002 -0.001 0.003"},
    {"box_tc", "0.02"},
    {"box_dmax", "0.95"},
    {"pair_mu", "0.7"},
    {"pair_mu2", "0.7"},
    {"pair_condim", "3"},
    {"pair_roll1", "0.0001"},
    {"pair_roll2", "0.0001"},
    {"pair_tc", "0.02"},
    {"pair_dmin", "0.9"},
    {"tendon_k", "2"},
    {"tendon_d", "0.1"},
    {"tendon_f", "0.01"},
    {"tendon_l", "0.1"},
    {"kp", "20"},
    {"kv", "1"},
    {"spin_kv", "0.5"},
    {"pid_kp", "5"},
    {"pid_ki", "2"},
    {"pid_kv", "0.3"},
    {"delay", "0.005"},
    {"sensor_delay", "0.003"},
    {"dc_k", "0.05"},
    {"dc_r", "2"},
    {"dc_l", "0.004"},
    {"cog_a", "0.002"},
    {"cog_ph", "0.2"},
    {"lugre0", "100"},
    {"lugre2", "0.02"},
    {"lugre4", "0.1"}};

std::string RobotXml(const std::map<std::string, std::string>& overrides) {
  std::map<std::string, std::string> values = overrides;
  values.insert(kRobotDefaults.begin(), kRobotDefaults.end());  // keeps the overrides
  return test::FillTemplate(kRobotTemplate, values);
}

// 500 steps under sines on every control (servo targets, the pid's position and velocity
// setpoints, pushes that make the box and the puck slide): the physics vectors x_1..x_500, each
// followed by the sensors (the delayed elbow angle)
std::vector<double> RobotRollout(const mjModel& m) {
  DataPtr d = MakeData(m);
  const StateDims dims(m);
  const int row = dims.nphys + dims.ns;
  std::vector<double> out(static_cast<size_t>(500) * row);
  const double amplitude[] = {0.8, 3.0, 0.6, 0.5, 9.0, 2.5};
  for (int k = 0; k < 500; ++k) {
    for (int i = 0; i < m.nu; ++i) {
      d->ctrl[i] = amplitude[i % 6] * std::sin(0.02 * (1 + 0.3 * i) * k + i);
    }
    mj_step(&m, d.get());
    double* x = out.data() + static_cast<size_t>(k) * row;
    GetPhysics(m, *d, x);
    std::copy(d->sensordata, d->sensordata + dims.ns, x + dims.nphys);
  }
  EXPECT_EQ(SimulationWarnings(*d), "");
  return out;
}

struct RobotCase {
  ParameterSpec spec;
  std::map<std::string, std::string> by_hand;  // the same value edited into the template
  double value;
};

class RobotWriterTest : public ::testing::TestWithParam<RobotCase> {};

TEST_P(RobotWriterTest, InPlaceWriteMatchesCompiledXml) {
  const RobotCase& c = GetParam();
  ModelPtr base = LoadModelFromString(RobotXml({}));
  ModelPtr edited_xml = LoadModelFromString(RobotXml(c.by_hand));
  ModelPtr written = CopyModel(*base);
  ParameterSet params(*written, {c.spec});
  params.Prepare(written.get());
  DataPtr scratch = MakeData(*written);
  params.Write(written.get(), scratch.get(), &c.value);
  double readback = 0;
  params.Read(*written, &readback);
  EXPECT_EQ(readback, c.value);
  EXPECT_EQ(params[0].Read(*edited_xml), c.value) << "the template edit is this value";

  const std::vector<double> traj_base = RobotRollout(*base);
  const std::vector<double> traj_xml = RobotRollout(*edited_xml);
  EXPECT_GT(test::MaxAbsDiff(traj_base, traj_xml), 1e-6) << "the edit has no effect";
  EXPECT_LE(test::MaxAbsDiff(RobotRollout(*written), traj_xml), 1e-12) << params[0].label();
}

INSTANTIATE_TEST_SUITE_P(
    Kinds, RobotWriterTest,
    ::testing::Values(
        RobotCase{Spec("tendon_damping", "elbow_spring"), {{"tendon_d", "0.3"}}, 0.3},
        RobotCase{Spec("tendon_stiffness", "elbow_spring"), {{"tendon_k", "3.5"}}, 3.5},
        RobotCase{Spec("tendon_frictionloss", "elbow_spring"), {{"tendon_f", "0.03"}}, 0.03},
        RobotCase{Spec("tendon_lengthspring", "elbow_spring", 0), {{"tendon_l", "0.25"}}, 0.25},
        RobotCase{Spec("geom_solref", "box", 0), {{"box_tc", "0.03"}}, 0.03},
        RobotCase{Spec("geom_solimp", "box", 1), {{"box_dmax", "0.99"}}, 0.99},
        RobotCase{Spec("pair_solref", "puck_floor", 0), {{"pair_tc", "0.05"}}, 0.05},
        RobotCase{Spec("pair_solimp", "puck_floor", 0), {{"pair_dmin", "0.8"}}, 0.8},
        RobotCase{Spec("pair_friction", "puck_floor", 0), {{"pair_mu", "0.3"}}, 0.3},
        RobotCase{Spec("pair_friction", "puck_floor", 1), {{"pair_mu2", "0.4"}}, 0.4},
        RobotCase{Spec("actuator_kp", "shoulder_servo"), {{"kp", "35"}}, 35},
        RobotCase{Spec("actuator_kv", "shoulder_servo"), {{"kv", "2.5"}}, 2.5},
        RobotCase{Spec("actuator_kv", "spin_servo"), {{"spin_kv", "1.2"}}, 1.2},
        RobotCase{Spec("actuator_kp", "elbow_pid"), {{"pid_kp", "8"}}, 8},
        RobotCase{Spec("actuator_kv", "elbow_pid"), {{"pid_kv", "0.7"}}, 0.7},
        RobotCase{Spec("actuator_ki", "elbow_pid"), {{"pid_ki", "4"}}, 4},
        RobotCase{Spec("actuator_delay", "shoulder_servo"), {{"delay", "0.009"}}, 0.009},
        RobotCase{Spec("sensor_delay", "elbow_angle"), {{"sensor_delay", "0.007"}}, 0.007},
        RobotCase{Spec("dcmotor_motorconst", "dc"), {{"dc_k", "0.07"}}, 0.07},
        RobotCase{Spec("dcmotor_resistance", "dc"), {{"dc_r", "2.5"}}, 2.5},
        RobotCase{Spec("dcmotor_inductance", "dc"), {{"dc_l", "0.006"}}, 0.006},
        RobotCase{Spec("dcmotor_cogging", "dc", 0), {{"cog_a", "0.004"}}, 0.004},
        RobotCase{Spec("dcmotor_cogging", "dc", 2), {{"cog_ph", "0.5"}}, 0.5},
        RobotCase{Spec("dcmotor_lugre", "dc", 0), {{"lugre0", "150"}}, 150},
        RobotCase{Spec("dcmotor_lugre", "dc", 2), {{"lugre2", "0.03"}}, 0.03},
        RobotCase{Spec("dcmotor_lugre", "dc", 4), {{"lugre4", "0.2"}}, 0.2},
        // the dead band's upper end (the elbow swings past it)
        RobotCase{Spec("tendon_lengthspring", "elbow_spring", 2), {{"tendon_l", "0.1 0.3"}}, 0.3}),
    [](const ::testing::TestParamInfo<RobotCase>& param_info) {
      return param_info.param.spec.kind + "_" + param_info.param.spec.object + "_" +
             std::to_string(param_info.param.spec.index);
    });

// the puck pair's rolling friction (index 3, 4), which acts with condim 6 only: the base and the
// hand-edited model both get condim 6; tolerances as above (the rolling puck does not spin: its
// torsional entry is tested in tests/core/identified_model_test.cc, where the box spins)
TEST(RobotWriterTest, PairRollingFrictionMatchesCompiledXml) {
  const std::map<std::string, std::string> condim6 = {{"pair_condim", "6"}};
  ModelPtr base = LoadModelFromString(RobotXml(condim6));
  const std::vector<double> traj_base = RobotRollout(*base);
  const std::pair<const char*, double> edits[2] = {{"pair_roll1", 0.003}, {"pair_roll2", 0.002}};
  for (int index = 3; index < 5; ++index) {
    const auto& [key, value] = edits[index - 3];
    SCOPED_TRACE(key);
    std::map<std::string, std::string> by_hand = condim6;
    by_hand[key] = FormatG17(value);
    ModelPtr edited_xml = LoadModelFromString(RobotXml(by_hand));
    ModelPtr written = CopyModel(*base);
    ParameterSet params(*written, {Spec("pair_friction", "puck_floor", index)});
    DataPtr scratch = MakeData(*written);
    params.Write(written.get(), scratch.get(), &value);
    EXPECT_EQ(params[0].Read(*edited_xml), value) << "the template edit is this value";
    const std::vector<double> traj_xml = RobotRollout(*edited_xml);
    EXPECT_GT(test::MaxAbsDiff(traj_base, traj_xml), 1e-6) << "the edit has no effect";
    EXPECT_LE(test::MaxAbsDiff(RobotRollout(*written), traj_xml), 1e-12);
  }
}

// the arm's inertial attributes of log-Cholesky variables (tests/core/inertial_by_hand.h)
std::map<std::string, std::string> InertialByHand(const double theta[10]) {
  const test::InertialText t = test::InertialByHand(theta);
  return {{"arm_mass", t.mass}, {"arm_com", t.pos}, {"arm_inertia", t.fullinertia}};
}

// body_inertial: each of the 10 variables written in place reproduces the model compiled from a
// full inertia written by hand. Truth: theta below; each variable moved by 0.1 (0.02 m for s, t).
// Tolerance 1e-10: MuJoCo's compiler and core eigen-decompose the same tensor with different
// roundoff (1e-16 relative), which 500 steps of a driven arm amplify to ~1e-13.
TEST(RobotWriterTest, BodyInertialEachVariableMatchesCompiledFullInertia) {
  const double theta[10] = {0.05, -1.6, -1.8, -2.1, 0.02, -0.01, 0.015, 0.02, 0.01, -0.15};
  ModelPtr base = LoadModelFromString(RobotXml(InertialByHand(theta)));
  const std::vector<double> traj_base = RobotRollout(*base);
  for (int i = 0; i < 10; ++i) {
    SCOPED_TRACE("variable " + std::to_string(i));
    double edited[10];
    std::copy(theta, theta + 10, edited);
    edited[i] += i < 4 ? 0.1 : 0.02;
    ModelPtr edited_xml = LoadModelFromString(RobotXml(InertialByHand(edited)));
    ModelPtr written = CopyModel(*base);
    ParameterSet params(*written, {Spec("body_inertial", "arm", i)});
    EXPECT_NEAR(params[0].Read(*base), theta[i], 1e-12) << "read from the compiled model";
    params.Prepare(written.get());
    DataPtr scratch = MakeData(*written);
    params.Write(written.get(), scratch.get(), &edited[i]);
    for (int k = 0; k < 10; ++k) {
      EXPECT_NEAR(Parameter::Resolve(*written, Spec("body_inertial", "arm", k)).Read(*written),
                  edited[k], 1e-12)
          << "variable " << k << " after the write";
    }
    const std::vector<double> traj_xml = RobotRollout(*edited_xml);
    EXPECT_GT(test::MaxAbsDiff(traj_base, traj_xml), 1e-6) << "the edit has no effect";
    EXPECT_LE(test::MaxAbsDiff(RobotRollout(*written), traj_xml), 1e-10);
  }
}

// a servo kind on an actuator of another form, and body_inertial of a point mass, are refused
TEST(RobotWriterTest, ServoAndInertialKindsRefuseOtherForms) {
  ModelPtr m = LoadModelFromString(RobotXml({}));
  auto message = [&](const ParameterSpec& spec) -> std::string {
    try {
      Parameter::Resolve(*m, spec);
    } catch (const ParameterError& e) {
      EXPECT_EQ(e.part(), ParameterSpecPart::kObject);
      return e.what();
    }
    return "";
  };
  EXPECT_NE(message(Spec("actuator_kp", "box_motor")).find("is not a <position> servo"),
            std::string::npos);
  EXPECT_NE(message(Spec("actuator_ki", "shoulder_servo")).find("is not a <pid> actuator"),
            std::string::npos);
  EXPECT_NE(message(Spec("actuator_kp", "spin_servo")).find("actuator_gain"), std::string::npos);
  EXPECT_NE(message(Spec("body_inertial", "world")).find("world body"), std::string::npos);
  ModelPtr point = LoadModelFromString(
      "<mujoco><worldbody><body name='p'><freejoint/><inertial pos='0 0 0' mass='1' "
      "diaginertia='1 1 2'/></body></worldbody></mujoco>");
  try {
    Parameter::Resolve(*point, Spec("body_inertial", "p"));
    ADD_FAILURE() << "a flat plate (1 + 1 = 2) accepted";
  } catch (const ParameterError& e) {
    EXPECT_NE(std::string(e.what()).find("not strictly physically consistent"), std::string::npos)
        << e.what();
  }
  // a delay without a linearly interpolated history buffer has no derivative
  ModelPtr hold = LoadModelFromString(
      "<mujoco><worldbody><body><joint name='j'/><geom size='.1'/></body></worldbody><actuator>"
      "<motor name='zoh' joint='j' delay='0.01' nsample='10'/><motor name='none' joint='j'/>"
      "</actuator></mujoco>");
  for (const auto& [actuator, expected] :
       {std::pair<std::string, std::string>{"zoh", "zero-order hold"},
        {"none", "no history buffer"}}) {
    try {
      Parameter::Resolve(*hold, Spec("actuator_delay", actuator));
      ADD_FAILURE() << actuator << " accepted";
    } catch (const ParameterError& e) {
      EXPECT_NE(std::string(e.what()).find(expected), std::string::npos) << e.what();
    }
  }
  // a dead-band spring has no one rest length
  ModelPtr band = LoadModelFromString(RobotXml({{"tendon_l", "0.1 0.3"}}));
  EXPECT_THROW(Parameter::Resolve(*band, Spec("tendon_lengthspring", "elbow_spring", 0)),
               ParameterError);
  EXPECT_EQ(Parameter::Resolve(*band, Spec("tendon_lengthspring", "elbow_spring", 2)).Read(*band),
            0.3);
}

TEST(ParameterTest, BadSpecsAreClearErrors) {
  ModelPtr m = LoadModelFromString(Xml({}));
  auto message = [&](const ParameterSpec& spec) -> std::string {
    try {
      Parameter::Resolve(*m, spec);
    } catch (const ParameterError& e) {
      return e.what();
    }
    return "";
  };
  EXPECT_NE(message(Spec("body_mas", "link")).find("unknown parameter kind 'body_mas'"),
            std::string::npos);
  const std::string unknown = message(Spec("body_mass", "lnk"));
  EXPECT_NE(unknown.find("no body named 'lnk'"), std::string::npos) << unknown;
  EXPECT_NE(unknown.find("link"), std::string::npos) << "hint lists the valid names: " << unknown;
  EXPECT_NE(message(Spec("geom_friction", "box", 3)).find("out of range"), std::string::npos);
  EXPECT_NE(message(Spec("body_mass", "world")).find("world body"), std::string::npos);
  ParameterSpec field;
  field.kind = "field";
  field.field = "dof_dampin";
  EXPECT_NE(message(field).find("no array named"), std::string::npos);
  field.field = "jnt_type";
  EXPECT_NE(message(field).find("not a floating-point"), std::string::npos);
  EXPECT_THROW(ParameterSet(*m, {Spec("body_mass", "link"), Spec("body_mass", "link")}),
               ParameterError);
}

TEST(ParameterTest, StagesFollowThePipeline) {
  ModelPtr m = LoadModelFromString(Xml({}));
  EXPECT_EQ(Parameter::Resolve(*m, Spec("body_mass", "link")).stage(), mjSTAGE_NONE);
  EXPECT_EQ(Parameter::Resolve(*m, Spec("joint_damping", "hinge")).stage(), mjSTAGE_POS);
  EXPECT_EQ(Parameter::Resolve(*m, Spec("joint_stiffness", "hinge")).stage(), mjSTAGE_POS);
  EXPECT_EQ(Parameter::Resolve(*m, Spec("actuator_gain", "act")).stage(), mjSTAGE_VEL);
  EXPECT_EQ(Parameter::Resolve(*m, Spec("geom_friction", "box")).stage(), mjSTAGE_NONE);
}

// ---------------------------------------------------------------------------------------------
// the kind table

TEST(KindTableTest, EveryKindIsCompleteAndNamedOnce) {
  const std::vector<ParameterKindInfo>& table = ParameterKindTable();
  ASSERT_EQ(table.size(), ParameterKindNames().size());
  std::set<std::string> names;
  for (size_t i = 0; i < table.size(); ++i) {
    const ParameterKindInfo& k = table[i];
    SCOPED_TRACE(k.name);
    // one row per enum value, in enum order, found by name and by kind
    EXPECT_EQ(static_cast<size_t>(k.kind), i);
    EXPECT_TRUE(names.insert(k.name).second) << "name listed twice";
    EXPECT_EQ(FindParameterKind(k.name), &k);
    EXPECT_EQ(&ParameterKindInfoOf(k.kind), &k);
    EXPECT_EQ(ParameterKindName(k.kind), k.name);
    EXPECT_EQ(ParameterKindNames()[i], k.name);
    // a writer, a stage, an object type with a display name, indices, units and docs
    EXPECT_NE(k.write_mjcf, nullptr);
    EXPECT_TRUE(k.stage == mjSTAGE_NONE || k.stage == mjSTAGE_POS || k.stage == mjSTAGE_VEL);
    EXPECT_EQ(k.object == mjOBJ_UNKNOWN, k.kind == ParameterKind::kField);
    EXPECT_EQ(k.num_indices == 0, k.kind == ParameterKind::kField);
    EXPECT_GT(std::string(k.object_name()).size(), 0u);
    for (const char* text : {k.indices, k.units, k.model_fields, k.mjcf}) {
      EXPECT_GT(std::string(text).size(), 0u);
    }
  }
  EXPECT_EQ(FindParameterKind("joint_dampin"), nullptr);
  EXPECT_STREQ(ParameterKindInfoOf(ParameterKind::kGeomFriction).object_name(), "geom");
  EXPECT_STREQ(ParameterKindInfoOf(ParameterKind::kField).object_name(), "mjModel array");
}

TEST(KindTableTest, IndexCountsOfASpecInAModel) {
  ModelPtr m = LoadModelFromString(Xml({}));
  EXPECT_EQ(ParameterIndexCount(*m, Spec("geom_friction", "box")), 3);
  EXPECT_EQ(ParameterIndexCount(*m, Spec("actuator_gain", "act")), mjNGAIN);
  EXPECT_EQ(ParameterIndexCount(*m, Spec("actuator_bias", "act")), mjNBIAS);
  EXPECT_EQ(ParameterIndexCount(*m, Spec("actuator_gear", "act")), 6);
  EXPECT_EQ(ParameterIndexCount(*m, Spec("body_inertia", "tip")), 3);
  EXPECT_EQ(ParameterIndexCount(*m, Spec("body_com", "tip")), 3);
  EXPECT_EQ(ParameterIndexCount(*m, Spec("body_mass", "tip")), 1);
  for (const char* joint : {"hinge", "ball", "free"}) {
    EXPECT_EQ(ParameterIndexCount(*m, Spec("joint_damping", joint)), 1) << joint;
  }
  ParameterSpec field;
  field.kind = "field";
  field.field = "dof_damping";
  EXPECT_EQ(ParameterIndexCount(*m, field), m->nv);
  EXPECT_THROW(ParameterIndexCount(*m, Spec("joint_dampin", "hinge")), ParameterError);
}

// MJCF has one damping, frictionloss, armature and stiffness per joint: every joint kind takes
// index 0 only, for every joint type, and index 1 gets one message, with or without a model
TEST(KindTableTest, JointKindsTakeIndexZeroForEveryJointType) {
  ModelPtr m = LoadModelFromString(Xml({}));
  for (const char* kind :
       {"joint_damping", "joint_frictionloss", "joint_armature", "joint_stiffness"}) {
    for (const char* joint : {"hinge", "ball", "free"}) {
      SCOPED_TRACE(std::string(kind) + " " + joint);
      EXPECT_NO_THROW(Parameter::Resolve(*m, Spec(kind, joint, 0)));
      const std::string expected = "index 1 is out of range for " + std::string(kind) +
                                   " of joint '" + joint +
                                   "' (0 only: " + FindParameterKind(kind)->indices + ")";
      for (int with_model = 0; with_model < 2; ++with_model) {
        try {
          if (with_model) {
            Parameter::Resolve(*m, Spec(kind, joint, 1));
          } else {
            CheckParameterSpec(Spec(kind, joint, 1));
          }
          ADD_FAILURE() << "index 1 accepted";
        } catch (const ParameterError& e) {
          EXPECT_EQ(e.message(), expected);
          EXPECT_EQ(e.part(), ParameterSpecPart::kIndex);
        }
      }
    }
  }
  // the decided wording for the damping of a ball joint
  try {
    Parameter::Resolve(*m, Spec("joint_damping", "ball", 1));
    ADD_FAILURE() << "index 1 accepted";
  } catch (const ParameterError& e) {
    EXPECT_STREQ(e.what(),
                 "index 1 is out of range for joint_damping of joint 'ball' (0 only: one MJCF "
                 "attribute per joint, applied to every dof)");
  }
}

// errors say which part of the spec is wrong, with core's hint
TEST(KindTableTest, ErrorsNameTheirPartAndHint) {
  ModelPtr m = LoadModelFromString(Xml({}));
  auto error = [&](const ParameterSpec& spec) -> ParameterError {
    try {
      Parameter::Resolve(*m, spec);
    } catch (const ParameterError& e) {
      return e;
    }
    return ParameterError("resolved");
  };
  const ParameterError kind = error(Spec("joint_dampng", "hinge"));
  EXPECT_EQ(kind.part(), ParameterSpecPart::kKind);
  EXPECT_EQ(kind.hint().rfind("did you mean 'joint_damping'? valid kinds: body_mass, ", 0), 0u)
      << kind.hint();
  const ParameterError object = error(Spec("joint_damping", "hnge"));
  EXPECT_EQ(object.part(), ParameterSpecPart::kObject);
  EXPECT_EQ(object.message(), "joint_damping: no joint named 'hnge'");
  EXPECT_EQ(object.hint(), "did you mean 'hinge'? valid joint names: hinge, ball, slide, free");
  EXPECT_EQ(std::string(object.what()), object.message() + " (hint: " + object.hint() + ")");
  EXPECT_EQ(error(Spec("geom_friction", "box", 3)).part(), ParameterSpecPart::kIndex);
  ParameterSpec field;
  field.kind = "field";
  field.field = "dof_dampin";
  EXPECT_EQ(error(field).part(), ParameterSpecPart::kField);
  EXPECT_EQ(error(field).hint().rfind("did you mean 'dof_damping'?", 0), 0u);
  EXPECT_EQ(error(Spec("body_mass", "world")).part(), ParameterSpecPart::kObject);
}

// the kinds table of docs/experiment-schema.md is the one core's table renders
std::string KindsMarkdown() {
  auto stage = [](int s) {
    return s == mjSTAGE_NONE ? "position" : s == mjSTAGE_POS ? "velocity" : "actuation";
  };
  std::string out =
      "| kind | object | index | units | mjModel | enters at | mj_setConst | written to MJCF as "
      "|\n| --- | --- | --- | --- | --- | --- | --- | --- |\n";
  for (const ParameterKindInfo& k : ParameterKindTable()) {
    const std::string range = k.num_indices == 0   ? "0..size-1"
                              : k.num_indices == 1 ? "0"
                                                   : "0.." + std::to_string(k.num_indices - 1);
    out += std::string("| `") + k.name + "` | " + k.object_name() + " | " + range + ": " +
           k.indices + " | " + k.units + " | " + k.model_fields + " | " + stage(k.stage) + " | " +
           (k.set_const ? "yes" : "no") + " | " + k.mjcf + " |\n";
  }
  return out;
}

TEST(KindTableTest, SchemaDocListsTheTable) {
  std::ifstream in(std::string(MJSYSID_SOURCE_DIR) + "/docs/experiment-schema.md");
  ASSERT_TRUE(in.good());
  std::stringstream text;
  text << in.rdbuf();
  const std::string doc = text.str();

  // every kind name is in the doc's table, and every kind of the doc's table is a kind
  const std::string begin = "<!-- kinds: begin -->\n", end = "<!-- kinds: end -->";
  const size_t from = doc.find(begin), to = doc.find(end);
  ASSERT_NE(from, std::string::npos);
  ASSERT_NE(to, std::string::npos);
  const std::string table = doc.substr(from + begin.size(), to - from - begin.size());
  for (const std::string& name : ParameterKindNames()) {
    EXPECT_NE(table.find("| `" + name + "` |"), std::string::npos) << name;
  }
  std::istringstream lines(table);
  for (std::string line; std::getline(lines, line);) {
    if (line.rfind("| `", 0) != 0) continue;
    const std::string name = line.substr(3, line.find('`', 3) - 3);
    EXPECT_NE(FindParameterKind(name), nullptr) << name << " is in the doc, not in core's table";
  }
  // and the rows say what the table says
  EXPECT_EQ(table, KindsMarkdown()) << "paste this between the markers:\n" << KindsMarkdown();
}

// A body's mass, inertia or centre of mass with no joint between the body and the world cannot
// move any state (issue 35): Resolve refuses it, naming the body and why, unless a force, torque
// or subtree sensor can read it; a body welded to a moving body, and a mocap body, as expected.
TEST(ParameterTest, BodiesWeldedToTheWorldAreRefusedUnlessASensorReadsThem) {
  const std::string bodies = R"(<worldbody>
      <body name="base" pos="0 0 1"><geom size="0.1" mass="1"/><site name="s"/>
        <body name="link"><joint name="j" axis="0 1 0"/><geom size="0.1" mass="1"/>
          <body name="tip" pos="0 0 -0.5"><geom size="0.1" mass="1"/></body>
        </body>
      </body>
      <body name="target" mocap="true"><geom size="0.1" mass="1" contype="0"/></body>
    </worldbody>)";
  ModelPtr plain = LoadModelFromString("<mujoco>" + bodies + "</mujoco>");
  for (const std::string kind : {"body_mass", "body_inertia", "body_com", "body_inertial"}) {
    SCOPED_TRACE(kind);
    for (const std::string body : {"base", "target"}) {
      try {
        Parameter::Resolve(*plain, Spec(kind, body));
        ADD_FAILURE() << body << " accepted";
      } catch (const ParameterError& e) {
        EXPECT_NE(std::string(e.what()).find("body '" + body + "' is welded to the world"),
                  std::string::npos)
            << e.what();
        EXPECT_EQ(e.part(), ParameterSpecPart::kObject);
      }
    }
    EXPECT_NO_THROW(Parameter::Resolve(*plain, Spec(kind, "tip")));  // welded to a moving link
  }
  try {
    Parameter::Resolve(*plain, Spec("body_mass", "base"));
  } catch (const ParameterError& e) {
    EXPECT_NE(std::string(e.what()).find("its mass cannot move any state"), std::string::npos);
  }
  // a force sensor on the base reads the weight of its subtree, the base's own included
  for (const std::string sensor : {R"(<force site="s"/>)", R"(<subtreecom body="world"/>)"}) {
    ModelPtr seen =
        LoadModelFromString("<mujoco>" + bodies + "<sensor>" + sensor + "</sensor></mujoco>");
    EXPECT_NO_THROW(Parameter::Resolve(*seen, Spec("body_mass", "base"))) << sensor;
  }
}

}  // namespace
}  // namespace mjsysid
