// every parameter writer against a model compiled from XML with the edited value
#include "core/parameters.h"

#include <gtest/gtest.h>

#include <cmath>
#include <map>
#include <string>
#include <vector>

#include "core/mujoco_env.h"
#include "core/state.h"
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
      <freejoint/>
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

std::string Xml(const std::map<std::string, double>& overrides) {
  std::string xml = kTemplate;
  for (const auto& [key, def] : kDefaults) {
    const auto it = overrides.find(key);
    const double value = it == overrides.end() ? def : it->second;
    const std::string token = "{" + key + "}";
    char buf[64];
    std::snprintf(buf, sizeof(buf), "%.17g", value);
    for (size_t pos = xml.find(token); pos != std::string::npos; pos = xml.find(token)) {
      xml.replace(pos, token.size(), buf);
    }
  }
  return xml;
}

// 500 steps under sine controls from the reference state: the physics vectors x_1..x_500
std::vector<double> Simulate(const mjModel& m) {
  DataPtr d = MakeData(m);
  const StateDims dims(m);
  std::vector<double> out(500 * dims.nphys);
  for (int k = 0; k < 500; ++k) {
    d->ctrl[0] = 2.0 * std::sin(0.02 * k);
    d->ctrl[1] = 1.5 * std::sin(0.015 * k + 1);
    d->ctrl[2] = 8.0 + 4.0 * std::sin(0.01 * k);
    d->ctrl[3] = 0.2 * std::sin(0.03 * k);
    mj_step(&m, d.get());
    GetPhysics(m, *d, out.data() + k * dims.nphys);
  }
  EXPECT_EQ(SimulationWarnings(*d), "");
  return out;
}

double MaxAbsDiff(const std::vector<double>& a, const std::vector<double>& b) {
  double worst = 0;
  for (size_t i = 0; i < a.size(); ++i) worst = std::max(worst, std::abs(a[i] - b[i]));
  return worst;
}

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
  EXPECT_GT(MaxAbsDiff(traj_base, traj_xml), 1e-6) << "edit of " << c.key << " has no effect";
  // ... and the in-place write reproduces the compiled model
  EXPECT_LE(MaxAbsDiff(traj_written, traj_xml), 1e-12) << params[0].label();
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
  EXPECT_LE(MaxAbsDiff(Simulate(*written), Simulate(*edited_xml)), 1e-12);
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
  EXPECT_LE(MaxAbsDiff(Simulate(*written), Simulate(*edited_xml)), 1e-12);
}

// the traps of ../shared/DESIGN.md §5 are real: without mj_setConst a simple body ignores its
// new mass, and the "same frame" flag ignores a new centre of mass
TEST(WriterTest, TrapsAreRealWithoutSetConstAndPrepare) {
  ModelPtr base = LoadModelFromString(Xml({}));
  const int slider = mj_name2id(base.get(), mjOBJ_BODY, "slider");
  const int link = mj_name2id(base.get(), mjOBJ_BODY, "link");
  ASSERT_NE(base->body_simple[slider], 0) << "the slider must be a simple body for this test";
  ASSERT_NE(base->body_sameframe[link], 0) << "the link must be in the same frame for this test";

  ModelPtr raw = CopyModel(*base);
  Parameter::Resolve(*raw, Spec("body_mass", "slider")).WriteRaw(raw.get(), 3.1);
  EXPECT_EQ(MaxAbsDiff(Simulate(*raw), Simulate(*base)), 0.0)
      << "MuJoCo no longer ignores a raw mass write on a simple body: update DESIGN.md";

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
  EXPECT_TRUE(rejected || MaxAbsDiff(traj, xml) > 1e-6)
      << "MuJoCo honours a raw body_ipos write on a same-frame body: update DESIGN.md";
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

}  // namespace
}  // namespace mjsysid
