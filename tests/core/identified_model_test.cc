// the identified MJCF of every parameter kind against a model compiled from XML edited by hand
#include "core/identified_model.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <map>
#include <ostream>
#include <sstream>
#include <string>
#include <vector>

#include "core/field_mjcf.h"
#include "core/mujoco_env.h"
#include "core/parameters.h"
#include "core/state.h"
#include "tests/core/inertial_by_hand.h"
#include "tests/temp_dir_test.h"
#include "tests/test_util.h"

namespace mjsysid {
namespace {

namespace fs = std::filesystem;

// a hinge link with an explicit inertial, a ball joint, a slider, a box on a free joint sliding on
// a floor (and a foot in an explicit contact pair with it), a tendon on the hinge, a payload with
// a full inertia swinging on two hinges, four motors and three servos (position, velocity, pid);
// {key} marks every value a test edits by hand
const char* kTemplate = R"(
<mujoco model="identified">
  <option timestep="0.002"/>
  {compiler}
  <worldbody>
    <geom name="floor" type="plane" size="5 5 .1" friction="0.1 0.001 0.0001"/>
    <body name="link" pos="0 0 2">
      <joint name="hinge" type="hinge" axis="0 1 0" damping="{damping}"
             frictionloss="{frictionloss}" armature="0.02" stiffness="{stiffness}"/>
      <inertial pos="{com_x} 0 0" mass="1.2" diaginertia="0.03 0.04 0.02"/>
      <geom type="capsule" fromto="0 0 0 0 0 -0.4" size="0.03" contype="0" conaffinity="0"/>
      <body name="tip" pos="0 0 -0.4" gravcomp="{gravcomp}">
        <joint name="ball" type="ball" damping="{ball_damping}" frictionloss="{ball_friction}"
               armature="{ball_armature}"/>
        <inertial pos="0.05 0 -0.2" mass="{tip_mass}" diaginertia="{ix} {iy} {iz}"/>
        <geom type="sphere" size="0.05" contype="0" conaffinity="0"/>
      </body>
    </body>
    <body name="slider" pos="2 0 1">
      <joint name="slide" type="slide" axis="1 0 0" armature="{slide_armature}"/>
      <inertial pos="0 0 0" mass="2" diaginertia="0.01 0.01 0.01"/>
      <geom type="sphere" size="0.05" contype="0" conaffinity="0"/>
    </body>
    <body name="box" pos="0 2 {box_z}">
      <joint name="free" type="free" damping="{free_damping}"/>
      <geom name="box" type="box" size=".1 .1 .1" mass="1" condim="4"
            friction="{box_mu} {box_torsion} 0.0001" solref="{box_timeconst} {box_dampratio}"
            solimp="{box_solimp0} {box_solimp1} {box_solimp2} {box_solimp3} {box_solimp4}"/>
      <geom name="foot" type="sphere" size="0.1" mass="0.1" pos="{foot_pos}" contype="0"
            conaffinity="0"/>
      <site name="push"/>
    </body>
    <body name="payload" pos="-2 0 1">
      <joint name="pitch" type="hinge" axis="0 1 0" damping="0.02"/>
      <joint name="roll" type="hinge" axis="1 0 0" damping="0.02"/>
      <inertial pos="{pl_com}" mass="{pl_mass}" fullinertia="{pl_inertia}"/>
    </body>
  </worldbody>
  <contact>
    <pair name="foot_floor" geom1="floor" geom2="foot" condim="6"
          friction="{pair_mu} {pair_mu2} {pair_torsion} 0.0001 0.0001"
          solref="{pair_timeconst} {pair_dampratio}"
          solimp="{pair_solimp0} {pair_solimp1} {pair_solimp2} {pair_solimp3} {pair_solimp4}"/>
  </contact>
  <tendon>
    <fixed name="spring" stiffness="{tendon_k}" damping="{tendon_d}" frictionloss="{tendon_f}"
           springlength="{tendon_l}">
      <joint joint="hinge" coef="1"/>
    </fixed>
  </tendon>
  <actuator>
    <general name="act" joint="hinge" biastype="affine" gainprm="{gain}" biasprm="0 {bias1} 0"
             gear="{gear}" delay="{delay}" nsample="8" interp="linear"/>
    <motor name="slide_motor" joint="slide"/>
    <motor name="box_motor" site="push" gear="1 0 0 0 0 {box_gear5}"/>
    <motor name="twist" joint="ball" gear="0.3 0.2 1"/>
    <position name="servo" joint="slide" kp="{kp}" kv="{kv}"/>
    <velocity name="vservo" joint="hinge" kv="{vkv}"/>
    <pid name="pid" joint="slide" kp="{pid_kp}" ki="{pid_ki}" kv="{pid_kv}"/>
    <dcmotor name="dc" joint="slide" motorconst="{dc_k}" resistance="{dc_r}" inductance="{dc_l}"
             cogging="{cog_a} {cog_p} {cog_ph}"
             lugre="{lugre0} {lugre1} {lugre2} {lugre3} {lugre4}"/>
  </actuator>
  <sensor>
    <jointpos name="slide_pos" joint="slide" delay="{sensor_delay}" nsample="5" interp="linear"/>
  </sensor>
</mujoco>)";

const std::map<std::string, std::string> kDefaults = {
    {"compiler", ""},
    {"damping", "0.2"},
    {"frictionloss", "0.05"},
    {"stiffness", "1.5"},
    {"com_x", "0"},
    {"ball_damping", "0.1"},
    {"ball_friction", "0.01"},
    {"ball_armature", "0.01"},
    {"tip_mass", "0.5"},
    {"ix", "0.01"},
    {"iy", "0.012"},
    {"iz", "0.005"},
    {"slide_armature", "0"},
    {"free_damping", "0.3"},
    {"box_mu", "0.6"},
    {"box_torsion", "0.005"},
    {"gain", "3"},
    {"bias1", "-1"},
    {"gear", "1"},
    {"box_gear5", "0.1"},
    {"gravcomp", "0.1"},
    {"foot_pos", "0 0 0"},
    {"box_z", "0.1"},
    {"box_timeconst", "0.02"},
    {"box_dampratio", "1"},
    {"box_solimp0", "0.9"},
    {"box_solimp1", "0.95"},
    {"box_solimp2", "0.001"},
    {"box_solimp3", "0.5"},
    {"box_solimp4", "2"},
    {"pair_mu", "0.7"},
    {"pair_timeconst", "0.02"},
    {"pair_mu2", "0.7"},
    {"pair_torsion", "0.005"},
    {"pair_dampratio", "1"},
    {"pair_solimp0", "0.9"},
    {"pair_solimp1", "0.95"},
    {"pair_solimp2", "0.001"},
    {"pair_solimp3", "0.5"},
    {"pair_solimp4", "2"},
    {"tendon_k", "0.5"},
    {"tendon_d", "0.1"},
    {"tendon_f", "0.01"},
    {"tendon_l", "0.1"},
    {"kp", "20"},
    {"kv", "1"},
    {"vkv", "0.5"},
    {"pid_kp", "5"},
    {"pid_ki", "2"},
    {"pid_kv", "0.3"},
    {"delay", "0.005"},
    {"sensor_delay", "0.003"},
    {"dc_k", "0.5"},
    {"dc_r", "2"},
    {"dc_l", "0.004"},
    {"cog_a", "0.02"},
    {"cog_p", "6"},
    {"cog_ph", "0.2"},
    {"lugre0", "100"},
    {"lugre1", "0.3"},
    {"lugre2", "0.02"},
    {"lugre3", "0.03"},
    {"lugre4", "0.1"},
    {"pl_com", "0.05 0.02 -0.2"},
    {"pl_mass", "0.8"},
    {"pl_inertia", "0.01 0.012 0.006 0.001 0 0.0005"}};

std::string Num(double v) {
  char buf[40];
  std::snprintf(buf, sizeof(buf), "%.17g", v);
  return buf;
}

// the template with the defaults, some replaced
std::string Xml(const std::map<std::string, std::string>& overrides) {
  std::map<std::string, std::string> values = overrides;
  values.insert(kDefaults.begin(), kDefaults.end());  // keeps the overrides
  return test::FillTemplate(kTemplate, values);
}

// 50 steps under sine controls: the physics vectors x_1..x_50, each with the sensors (a delayed
// sensor's delay shows only there)
std::vector<double> Rollout(const mjModel& m) { return test::SineRollout(m, 50, 0.2, true); }

ParameterSpec Spec(const std::string& kind, const std::string& object, int index = 0) {
  ParameterSpec s;
  s.kind = kind;
  s.object = object;
  s.index = index;
  return s;
}

// a fresh folder per test holding the base model file
class IdentifiedModelTest : public test::TempDirTest {
 protected:
  // the template (with overrides) as a model file
  std::string ModelFile(const std::map<std::string, std::string>& overrides = {}) {
    const std::string path = (dir_ / "model.xml").string();
    std::ofstream(path) << Xml(overrides);
    return path;
  }
};

struct KindCase {
  ParameterSpec spec;
  double value;                                // the identified value
  std::map<std::string, std::string> by_hand;  // the same value edited into the template
};

// gtest's name of a case in failure messages
void PrintTo(const KindCase& c, std::ostream* os) {
  *os << c.spec.kind << " " << c.spec.object << "[" << c.spec.index << "] = " << c.value;
}

class IdentifiedKindTest : public IdentifiedModelTest,
                           public ::testing::WithParamInterface<KindCase> {};

TEST_P(IdentifiedKindTest, MatchesXmlEditedByHand) {
  const KindCase& c = GetParam();
  const std::string path = ModelFile();
  std::vector<std::string> warnings;
  const std::string xml = IdentifiedModelXml(path, {c.spec}, {c.value}, &warnings);
  EXPECT_TRUE(warnings.empty()) << warnings.front();

  ModelPtr base = LoadModel(path);
  ModelPtr by_hand = LoadModelFromString(Xml(c.by_hand));
  ModelPtr identified = LoadModelFromString(xml);

  // the value is in the identified model, at full precision
  const Parameter p = Parameter::Resolve(*identified, c.spec);
  EXPECT_EQ(p.Read(*identified), c.value) << p.label();
  EXPECT_EQ(p.Read(*by_hand), c.value) << p.label();

  // every mjtNum array of mjModel agrees with the hand-edited model, and so does a rollout
  ASSERT_EQ(identified->nbody, by_hand->nbody);
  ASSERT_EQ(identified->nv, by_hand->nv);
  EXPECT_EQ(DifferingArrays(*identified, *by_hand, 1e-12), "");
  const std::vector<double> traj_base = Rollout(*base);
  const std::vector<double> traj_hand = Rollout(*by_hand);
  EXPECT_GT(test::MaxAbsDiff(traj_base, traj_hand), 1e-9)
      << "the edit has no effect on the rollout";
  EXPECT_LE(test::MaxAbsDiff(Rollout(*identified), traj_hand), 1e-12) << p.label();
}

const double kScale = 0.8 / 0.5;  // body_mass_inertia: tip mass 0.5 -> 0.8

const std::vector<KindCase> kCases = {
    KindCase{Spec("body_mass", "tip"), 0.7, {{"tip_mass", "0.7"}}},
    KindCase{Spec("body_mass_inertia", "tip"),
             0.8,
             {{"tip_mass", "0.8"},
              {"ix", Num(0.01 * kScale)},
              {"iy", Num(0.012 * kScale)},
              {"iz", Num(0.005 * kScale)}}},
    KindCase{Spec("body_inertia", "tip", 1), 0.014, {{"iy", "0.014"}}},
    KindCase{Spec("body_com", "link", 0), 0.08, {{"com_x", "0.08"}}},
    KindCase{Spec("joint_damping", "hinge"), 0.55, {{"damping", "0.55"}}},
    KindCase{Spec("joint_damping", "ball"), 0.3, {{"ball_damping", "0.3"}}},
    KindCase{Spec("joint_damping", "free"), 1.7, {{"free_damping", "1.7"}}},
    KindCase{Spec("joint_frictionloss", "hinge"), 0.2, {{"frictionloss", "0.2"}}},
    KindCase{Spec("joint_frictionloss", "ball"), 0.04, {{"ball_friction", "0.04"}}},
    KindCase{Spec("joint_armature", "ball"), 0.05, {{"ball_armature", "0.05"}}},
    KindCase{Spec("joint_armature", "slide"), 0.4, {{"slide_armature", "0.4"}}},
    KindCase{Spec("joint_stiffness", "hinge"), 4.0, {{"stiffness", "4"}}},
    KindCase{Spec("geom_friction", "box", 0), 0.3, {{"box_mu", "0.3"}}},
    KindCase{Spec("geom_friction", "box", 1), 0.05, {{"box_torsion", "0.05"}}},
    KindCase{Spec("actuator_gain", "act", 0), 5.0, {{"gain", "5"}}},
    KindCase{Spec("actuator_bias", "act", 1), -2.5, {{"bias1", "-2.5"}}},
    KindCase{Spec("actuator_gear", "act", 0), 1.8, {{"gear", "1.8"}}},
    KindCase{Spec("actuator_gear", "box_motor", 5), 0.25, {{"box_gear5", "0.25"}}},
    KindCase{Spec("tendon_damping", "spring"), 0.3, {{"tendon_d", "0.3"}}},
    KindCase{Spec("tendon_stiffness", "spring"), 3.5, {{"tendon_k", "3.5"}}},
    KindCase{Spec("tendon_frictionloss", "spring"), 0.03, {{"tendon_f", "0.03"}}},
    KindCase{Spec("tendon_lengthspring", "spring", 0), 0.25, {{"tendon_l", "0.25"}}},
    KindCase{Spec("tendon_lengthspring", "spring", 1), -0.05, {{"tendon_l", "-0.05 0.1"}}},
    KindCase{Spec("geom_solref", "box", 0), 0.03, {{"box_timeconst", "0.03"}}},
    KindCase{Spec("geom_solimp", "box", 1), 0.99, {{"box_solimp1", "0.99"}}},
    KindCase{Spec("pair_solref", "foot_floor", 0), 0.05, {{"pair_timeconst", "0.05"}}},
    KindCase{Spec("pair_solimp", "foot_floor", 1), 0.97, {{"pair_solimp1", "0.97"}}},
    KindCase{Spec("pair_friction", "foot_floor", 0), 0.9, {{"pair_mu", "0.9"}}},
    KindCase{Spec("actuator_kp", "servo"), 35, {{"kp", "35"}}},
    KindCase{Spec("actuator_kv", "servo"), 2.5, {{"kv", "2.5"}}},
    KindCase{Spec("actuator_kv", "vservo"), 1.2, {{"vkv", "1.2"}}},
    KindCase{Spec("actuator_kp", "pid"), 8, {{"pid_kp", "8"}}},
    KindCase{Spec("actuator_kv", "pid"), 0.7, {{"pid_kv", "0.7"}}},
    KindCase{Spec("actuator_ki", "pid"), 4, {{"pid_ki", "4"}}},
    KindCase{Spec("actuator_delay", "act"), 0.009, {{"delay", "0.009"}}},
    KindCase{Spec("sensor_delay", "slide_pos"), 0.007, {{"sensor_delay", "0.007"}}},
    KindCase{Spec("dcmotor_motorconst", "dc"), 0.7, {{"dc_k", "0.7"}}},
    KindCase{Spec("dcmotor_resistance", "dc"), 2.5, {{"dc_r", "2.5"}}},
    KindCase{Spec("dcmotor_inductance", "dc"), 0.006, {{"dc_l", "0.006"}}},
    KindCase{Spec("dcmotor_cogging", "dc", 0), 0.04, {{"cog_a", "0.04"}}},
    KindCase{Spec("dcmotor_lugre", "dc", 0), 150, {{"lugre0", "150"}}},
    // every further index with its own meaning (the coverage table in docs/numerics.md); the
    // pair's torsional entry acts because the pair has condim 6 (its rolling entries do not reach
    // this scene: tests/core/parameters_test.cc; the dead band's upper end: below)
    KindCase{Spec("geom_solref", "box", 1), 0.7, {{"box_dampratio", "0.7"}}},
    KindCase{Spec("geom_solimp", "box", 0), 0.8, {{"box_solimp0", "0.8"}}},
    KindCase{Spec("geom_solimp", "box", 2), 0.003, {{"box_solimp2", "0.003"}}},
    KindCase{Spec("geom_solimp", "box", 3), 0.3, {{"box_solimp3", "0.3"}}},
    KindCase{Spec("geom_solimp", "box", 4), 3, {{"box_solimp4", "3"}}},
    KindCase{Spec("pair_solref", "foot_floor", 1), 0.7, {{"pair_dampratio", "0.7"}}},
    KindCase{Spec("pair_solimp", "foot_floor", 0), 0.8, {{"pair_solimp0", "0.8"}}},
    KindCase{Spec("pair_solimp", "foot_floor", 2), 0.003, {{"pair_solimp2", "0.003"}}},
    KindCase{Spec("pair_solimp", "foot_floor", 3), 0.3, {{"pair_solimp3", "0.3"}}},
    KindCase{Spec("pair_solimp", "foot_floor", 4), 3, {{"pair_solimp4", "3"}}},
    KindCase{Spec("pair_friction", "foot_floor", 1), 0.4, {{"pair_mu2", "0.4"}}},
    KindCase{Spec("pair_friction", "foot_floor", 2), 0.05, {{"pair_torsion", "0.05"}}},
    KindCase{Spec("dcmotor_cogging", "dc", 1), 7, {{"cog_p", "7"}}},
    KindCase{Spec("dcmotor_cogging", "dc", 2), 0.5, {{"cog_ph", "0.5"}}},
    KindCase{Spec("dcmotor_lugre", "dc", 1), 0.5, {{"lugre1", "0.5"}}},
    KindCase{Spec("dcmotor_lugre", "dc", 2), 0.03, {{"lugre2", "0.03"}}},
    KindCase{Spec("dcmotor_lugre", "dc", 3), 0.045, {{"lugre3", "0.045"}}},
    KindCase{Spec("dcmotor_lugre", "dc", 4), 0.2, {{"lugre4", "0.2"}}}};

INSTANTIATE_TEST_SUITE_P(EveryKind, IdentifiedKindTest, ::testing::ValuesIn(kCases),
                         [](const ::testing::TestParamInfo<KindCase>& param_info) {
                           return param_info.param.spec.kind + "_" + param_info.param.spec.object +
                                  "_" + std::to_string(param_info.param.spec.index);
                         });

// every kind of the table but field and body_inertial (tested below) has a case above
TEST(IdentifiedKindCoverage, EveryKindHasACase) {
  for (const ParameterKindInfo& k : ParameterKindTable()) {
    if (k.kind == ParameterKind::kField || k.kind == ParameterKind::kBodyInertial) continue;
    bool covered = false;
    for (const KindCase& c : kCases) covered = covered || c.spec.kind == k.name;
    EXPECT_TRUE(covered) << k.name;
  }
}

// the upper end of a tendon spring's dead band (tendon_lengthspring index 2): the base band
// [-0.1, -0.05] lies below most of the hinge's swing, so moving its upper end to 0.05 acts (the
// template's one-value spring at 0.1 is above the swing, where the upper end has no effect)
TEST_F(IdentifiedModelTest, TendonDeadBandUpperEndMatchesXmlEditedByHand) {
  const std::string path = ModelFile({{"tendon_l", "-0.1 -0.05"}});
  const ParameterSpec spec = Spec("tendon_lengthspring", "spring", 2);
  std::vector<std::string> warnings;
  const std::string xml = IdentifiedModelXml(path, {spec}, {0.05}, &warnings);
  EXPECT_TRUE(warnings.empty()) << warnings.front();
  ModelPtr by_hand = LoadModelFromString(Xml({{"tendon_l", "-0.1 0.05"}}));
  ModelPtr identified = LoadModelFromString(xml);
  EXPECT_EQ(Parameter::Resolve(*identified, spec).Read(*identified), 0.05);
  EXPECT_EQ(DifferingArrays(*identified, *by_hand, 1e-12), "");
  const std::vector<double> traj_hand = Rollout(*by_hand);
  EXPECT_GT(test::MaxAbsDiff(Rollout(*LoadModel(path)), traj_hand), 1e-9) << "no effect";
  EXPECT_LE(test::MaxAbsDiff(Rollout(*identified), traj_hand), 1e-12);
}

// body_inertial: a log-Cholesky variable of the payload written into MJCF compiles to the model
// whose full inertia is written by hand (tests/core/inertial_by_hand.h) from the same variables
TEST_F(IdentifiedModelTest, BodyInertialMatchesFullInertiaByHand) {
  const double theta[10] = {-0.1, -2.0, -1.9, -2.2, 0.01, -0.02, 0.005, 0.05, 0.02, -0.2};
  const test::InertialText base_text = test::InertialByHand(theta);
  const std::string path = ModelFile({{"pl_mass", base_text.mass},
                                      {"pl_com", base_text.pos},
                                      {"pl_inertia", base_text.fullinertia}});
  for (int i = 0; i < 10; ++i) {
    SCOPED_TRACE("variable " + std::to_string(i));
    double edited[10];
    std::copy(theta, theta + 10, edited);
    edited[i] += i < 4 ? 0.2 : 0.03;
    std::vector<std::string> warnings;
    const std::string xml =
        IdentifiedModelXml(path, {Spec("body_inertial", "payload", i)}, {edited[i]}, &warnings);
    EXPECT_TRUE(warnings.empty()) << warnings.front();
    const test::InertialText t = test::InertialByHand(edited);
    ModelPtr by_hand = LoadModelFromString(
        Xml({{"pl_mass", t.mass}, {"pl_com", t.pos}, {"pl_inertia", t.fullinertia}}));
    ModelPtr identified = LoadModelFromString(xml);
    for (int k = 0; k < 10; ++k) {
      EXPECT_NEAR(
          Parameter::Resolve(*identified, Spec("body_inertial", "payload", k)).Read(*identified),
          edited[k], 1e-12);
    }
    // the two eigen-decompositions (MuJoCo's compiler, core) differ by roundoff: the inertial
    // arrays agree to 1e-12 relative up to the principal axes' signs, so compare rollouts
    const std::vector<double> traj_hand = Rollout(*by_hand);
    EXPECT_GT(test::MaxAbsDiff(Rollout(*LoadModel(path)), traj_hand), 1e-9) << "no effect";
    EXPECT_LE(test::MaxAbsDiff(Rollout(*identified), traj_hand), 1e-12);
  }
}

ParameterSpec Field(const std::string& array, int index) {
  ParameterSpec s;
  s.kind = "field";
  s.field = array;
  s.index = index;
  return s;
}

// field targets with an MJCF home: the same value edited by hand into the attribute. Rows:
// body 2 tip; geom 4 box; joint/dof 0 hinge; pair 0; tendon 0; actuator output 2 box_motor
const std::vector<KindCase> kFieldCases = {
    KindCase{Field("body_mass", 2), 0.7, {{"tip_mass", "0.7"}}},
    KindCase{Field("body_inertia", 3 * 2 + 1), 0.014, {{"iy", "0.014"}}},
    KindCase{Field("body_gravcomp", 2), 0.5, {{"gravcomp", "0.5"}}},
    KindCase{Field("jnt_stiffness", 0), 4.0, {{"stiffness", "4"}}},
    KindCase{Field("dof_damping", 0), 0.55, {{"damping", "0.55"}}},
    KindCase{Field("dof_frictionloss", 0), 0.2, {{"frictionloss", "0.2"}}},
    KindCase{Field("geom_friction", 3 * 4), 0.3, {{"box_mu", "0.3"}}},
    KindCase{Field("geom_solref", 2 * 4), 0.03, {{"box_timeconst", "0.03"}}},
    KindCase{Field("pair_friction", 0), 0.9, {{"pair_mu", "0.9"}}},
    KindCase{Field("pair_solref", 0), 0.05, {{"pair_timeconst", "0.05"}}},
    KindCase{Field("pair_solimp", 1), 0.97, {{"pair_solimp1", "0.97"}}},
    KindCase{Field("tendon_stiffness", 0), 2.0, {{"tendon_k", "2"}}},
    KindCase{Field("tendon_damping", 0), 0.3, {{"tendon_d", "0.3"}}},
    KindCase{Field("actuator_gainprm", 0), 5.0, {{"gain", "5"}}},
    KindCase{Field("actuator_biasprm", 1), -2.5, {{"bias1", "-2.5"}}},
    KindCase{Field("actuator_gear", 6 * 2 + 5), 0.25, {{"box_gear5", "0.25"}}}};

INSTANTIATE_TEST_SUITE_P(FieldArrays, IdentifiedKindTest, ::testing::ValuesIn(kFieldCases),
                         [](const ::testing::TestParamInfo<KindCase>& param_info) {
                           return param_info.param.spec.field + "_" +
                                  std::to_string(param_info.param.spec.index);
                         });

// the model compiled from the template with one value written by the core's writers: what a fit
// returns (the identified text must compile to it)
ModelPtr Fitted(const std::string& path, const std::vector<ParameterSpec>& specs,
                const std::vector<double>& values) {
  ModelPtr m = LoadModel(path);
  const ParameterSet params(*m, specs);
  params.Prepare(m.get());
  DataPtr scratch = MakeData(*m);
  params.Write(m.get(), scratch.get(), values.data());
  return m;
}

// every array of the field table, changed on one row of the template, compiles back from the
// identified text to the fitted model
TEST_F(IdentifiedModelTest, EveryFieldArrayWithAnMjcfHomeIsWritten) {
  const std::string path = ModelFile();
  ModelPtr base = LoadModel(path);
  for (const FieldMjcfInfo& f : FieldMjcfTable()) {
    SCOPED_TRACE(f.array);
    const std::string array = f.array;
    // a row whose object has the attribute: the tip (body), the box (geom), else the first
    const int row = f.object == mjOBJ_BODY ? 2 : f.object == mjOBJ_GEOM ? 4 : 0;
    // a spring's rest length range grows at its upper end (a lower end above it does not compile)
    const int column = array == "tendon_lengthspring" ? 1 : 0;
    const ParameterSpec spec = Field(array, row * ParameterIndexCount(*base, Field(array, 0)) /
                                                    (array.rfind("body_", 0) == 0   ? base->nbody
                                                     : array.rfind("geom_", 0) == 0 ? base->ngeom
                                                                                    : 1) +
                                                column);
    const double value = 1.05 * Parameter::Resolve(*base, spec).Read(*base) + 0.001;
    std::vector<std::string> warnings;
    const std::string xml = IdentifiedModelXml(path, {spec}, {value}, &warnings);
    EXPECT_TRUE(warnings.empty()) << warnings.front();
    ModelPtr fitted = Fitted(path, {spec}, {value});
    EXPECT_EQ(DifferingArrays(*LoadModelFromString(xml), *fitted, 1e-12), "");
    EXPECT_NE(DifferingArrays(*base, *fitted, 1e-12), "") << "the edit changes nothing";
  }
}

// the field table as the markdown rows of docs/experiment-schema.md
std::string FieldArraysMarkdown() {
  std::string out = "| `field` array | written to MJCF as |\n| --- | --- |\n";
  for (const FieldMjcfInfo& f : FieldMjcfTable()) {
    out += std::string("| `") + f.array + "` | " + f.attribute + " |\n";
  }
  return out;
}

// the doc lists the field table as it is
TEST(FieldMjcfTableTest, SchemaDocListsTheTable) {
  std::ifstream in(std::string(MJSYSID_SOURCE_DIR) + "/docs/experiment-schema.md");
  ASSERT_TRUE(in.good());
  std::stringstream text;
  text << in.rdbuf();
  const std::string doc = text.str();
  const std::string begin = "<!-- field arrays: begin -->\n", end = "<!-- field arrays: end -->";
  const size_t from = doc.find(begin), to = doc.find(end);
  ASSERT_NE(from, std::string::npos);
  ASSERT_NE(to, std::string::npos);
  EXPECT_EQ(doc.substr(from + begin.size(), to - from - begin.size()), FieldArraysMarkdown())
      << "paste this between the markers:\n"
      << FieldArraysMarkdown();
}

// an array without an MJCF home, and one dof of a joint with several (one attribute per joint),
// are not written: a warning each, and the text is the model's
TEST_F(IdentifiedModelTest, FieldsWithoutAnMjcfHomeWarn) {
  const std::string path = ModelFile();
  const std::vector<std::pair<ParameterSpec, std::string>> cases = {
      {Field("body_pos", 3 * 3), "'field:body_pos[9]' (field body_pos[9])"},        // slider x
      {Field("dof_damping", 5), "'field:dof_damping[5]' (field dof_damping[5])"}};  // free joint
  std::vector<ParameterSpec> specs;
  for (const auto& c : cases) specs.push_back(c.first);
  std::vector<std::string> warnings;
  const std::string xml = IdentifiedModelXml(path, specs, {2.5, 0.9}, &warnings);
  ASSERT_EQ(warnings.size(), cases.size());
  for (size_t i = 0; i < cases.size(); ++i) {
    EXPECT_NE(warnings[i].find(cases[i].second + " has no MJCF attribute"), std::string::npos)
        << warnings[i];
    EXPECT_NE(warnings[i].find("identified model"), std::string::npos) << warnings[i];
  }
  ModelPtr base = LoadModel(path);
  EXPECT_EQ(DifferingArrays(*LoadModelFromString(xml), *base, 1e-12), "");
}

// compiler options that rescale or replace inertials: the identified text compiles to the fitted
// model (the written value and every other body as compiled), for a body parameter each
struct CompilerCase {
  std::string name;
  std::map<std::string, std::string> overrides;  // the compiler clause and template values
  ParameterSpec spec;
  double value;
};

// gtest's name of a case in failure messages
void PrintTo(const CompilerCase& c, std::ostream* os) { *os << c.name; }

class IdentifiedCompilerTest : public IdentifiedModelTest,
                               public ::testing::WithParamInterface<CompilerCase> {};

TEST_P(IdentifiedCompilerTest, CompilesToTheFittedModel) {
  const CompilerCase& c = GetParam();
  const std::string path = ModelFile(c.overrides);
  std::vector<std::string> warnings;
  const std::string xml = IdentifiedModelXml(path, {c.spec}, {c.value}, &warnings);
  EXPECT_TRUE(warnings.empty()) << warnings.front();
  ModelPtr base = LoadModel(path);
  ModelPtr fitted = Fitted(path, {c.spec}, {c.value});
  ModelPtr identified = LoadModelFromString(xml);
  EXPECT_EQ(Parameter::Resolve(*identified, c.spec).Read(*identified), c.value);
  EXPECT_EQ(DifferingArrays(*identified, *fitted, 1e-12), "");
  EXPECT_GT(test::MaxAbsDiff(Rollout(*base), Rollout(*fitted)), 1e-9) << "the edit changes nothing";
  EXPECT_LE(test::MaxAbsDiff(Rollout(*identified), Rollout(*fitted)), 1e-12);
}

const std::vector<CompilerCase> kCompilerCases = {
    // explicit inertials ignored: every body's from its geoms
    {"inertiafromgeom",
     {{"compiler", R"(<compiler inertiafromgeom="true"/>)"}},
     Spec("body_mass", "tip"),
     0.7},
    // every mass and inertia scaled to a total of 10 kg
    {"settotalmass",
     {{"compiler", R"(<compiler settotalmass="10"/>)"}},
     Spec("body_mass", "tip"),
     0.7},
    // masses below 0.9 raised to it (the tip's 0.5; the identified 0.7 too)
    {"boundmass", {{"compiler", R"(<compiler boundmass="0.9"/>)"}}, Spec("body_mass", "tip"), 0.7},
    // inertias below 0.011 raised to it (the tip's x and z; the identified y 0.008 too)
    {"boundinertia",
     {{"compiler", R"(<compiler boundinertia="0.011"/>)"}},
     Spec("body_inertia", "tip", 1),
     0.008},
    // the tip's inertia 0.01 + 0.012 < 0.03 balanced; the link's centre of mass identified
    {"balanceinertia",
     {{"compiler", R"(<compiler balanceinertia="true"/>)"}, {"iz", "0.03"}},
     Spec("body_com", "link", 0),
     0.08},
    // geom inertia from the groups 0..2 only, and several options at once
    {"inertiagrouprange_and_more",
     {{"compiler",
       R"(<compiler inertiagrouprange="0 2" inertiafromgeom="true" settotalmass="7" boundmass="0.2"/>)"}},
     Spec("body_mass_inertia", "box"),
     1.6},
};

const std::vector<CompilerCase> kAlign = {
    // the box's frame moved to its inertial frame (off centre: the foot is); the box in the air
    // (on the floor, differences of 1e-16 from the realignment become the contact solver's 1e-8)
    {"alignfree_mass",
     {{"compiler", R"(<compiler alignfree="true"/>)"}, {"foot_pos", "0.05 0.02 0"}, {"box_z", "1"}},
     Spec("body_mass", "box"),
     1.4},
};
INSTANTIATE_TEST_SUITE_P(Align, IdentifiedCompilerTest, ::testing::ValuesIn(kAlign),
                         [](const ::testing::TestParamInfo<CompilerCase>& param_info) {
                           return param_info.param.name;
                         });

INSTANTIATE_TEST_SUITE_P(Options, IdentifiedCompilerTest, ::testing::ValuesIn(kCompilerCases),
                         [](const ::testing::TestParamInfo<CompilerCase>& param_info) {
                           return param_info.param.name;
                         });

// asset files resolve when the text is saved in another folder: a mesh under meshdir (relative to
// the model's folder) and an included file; a box geom fitted to the mesh's bounding box (fitaabb)
TEST_F(IdentifiedModelTest, AssetPathsResolveFromAnotherFolder) {
  fs::create_directories(dir_ / "model" / "meshes");
  fs::create_directories(dir_ / "out");
  std::ofstream(dir_ / "model" / "meshes" / "tet.obj")
      << "v 0 0 0\nv 0.2 0 0\nv 0 0.2 0\nv 0 0 0.2\nf 1 3 2\nf 1 2 4\nf 1 4 3\nf 2 3 4\n";
  std::ofstream(dir_ / "model" / "part.xml") << R"(<mujoco>
  <body name="rock" pos="0 0 1">
    <joint name="rock_hinge" axis="0 1 0" damping="0.1"/>
    <geom type="mesh" mesh="tet"/>
    <geom type="box" mesh="tet" pos="0.3 0 0"/>
  </body>
</mujoco>)";
  const std::string path = (dir_ / "model" / "assets.xml").string();
  std::ofstream(path) << R"(<mujoco model="assets">
  <compiler meshdir="meshes" fitaabb="true"/>
  <asset><mesh name="tet" file="tet.obj"/></asset>
  <worldbody><include file="part.xml"/></worldbody>
  <actuator><motor name="m" joint="rock_hinge"/></actuator>
</mujoco>)";
  const std::vector<ParameterSpec> specs = {Spec("body_mass", "rock"),
                                            Spec("joint_damping", "rock_hinge")};
  const std::vector<double> values = {0.9, 0.4};
  std::vector<std::string> warnings;
  const std::string xml = IdentifiedModelXml(path, specs, values, &warnings);
  EXPECT_TRUE(warnings.empty()) << warnings.front();
  EXPECT_EQ(xml.find("<include"), std::string::npos);

  // saved in another folder, loaded from there
  const std::string out = (dir_ / "out" / "assets_identified.xml").string();
  std::ofstream(out) << xml;
  ModelPtr identified = LoadModel(out);
  ModelPtr fitted = Fitted(path, specs, values);
  ModelPtr base = LoadModel(path);
  EXPECT_EQ(DifferingArrays(*identified, *fitted, 1e-12), "");
  EXPECT_GT(test::MaxAbsDiff(Rollout(*base), Rollout(*fitted)), 1e-9);
  EXPECT_LE(test::MaxAbsDiff(Rollout(*identified), Rollout(*fitted)), 1e-12);
}

// with alignfree a free body's frame follows its centre of mass: an identified centre of mass
// moves the frame the text compiles to, so the file cannot hold the fitted model: warnings
TEST_F(IdentifiedModelTest, CentreOfMassOfAnAlignedFreeBodyWarns) {
  const std::string path = ModelFile({{"compiler", R"(<compiler alignfree="true"/>)"}});
  std::vector<std::string> warnings;
  IdentifiedModelXml(path, {Spec("body_com", "box", 0)}, {0.02}, &warnings);
  ASSERT_EQ(warnings.size(), 2u);
  EXPECT_NE(warnings[0].find("identified model: 'body_com:box[0]' reads "), std::string::npos)
      << warnings[0];
  EXPECT_NE(warnings[1].find("identified model: compiled from its text, it differs from the "
                             "fitted model in qpos0"),
            std::string::npos)
      << warnings[1];
}

// several values at once, each in its element; bad input is an error, not a file
TEST_F(IdentifiedModelTest, SeveralValuesAndBadInput) {
  const std::string path = ModelFile();
  std::vector<std::string> warnings;
  const std::string xml = IdentifiedModelXml(
      path, {Spec("joint_damping", "ball"), Spec("body_com", "link", 0)}, {0.3, 0.08}, &warnings);
  EXPECT_TRUE(warnings.empty());
  ModelPtr by_hand = LoadModelFromString(Xml({{"ball_damping", "0.3"}, {"com_x", "0.08"}}));
  EXPECT_EQ(DifferingArrays(*LoadModelFromString(xml), *by_hand, 1e-12), "");

  EXPECT_THROW(IdentifiedModelXml(path, {Spec("joint_damping", "ball", 1)}, {0.3}, &warnings),
               ParameterError);
  EXPECT_THROW(IdentifiedModelXml(path, {Spec("joint_damping", "ball")}, {}, &warnings),
               std::invalid_argument);
  EXPECT_THROW(IdentifiedModelXml((dir_ / "missing.xml").string(), {}, {}, &warnings),
               ModelLoadError);
}

}  // namespace
}  // namespace mjsysid
