#include "core/mujoco_env.h"

#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <string>

namespace mjsysid {
namespace {

const std::string kModels = MJSYSID_MODELS_DIR;

TEST(MujocoEnvTest, LoadsShippedModel) {
  ModelPtr m = LoadModel(kModels + "/pendulum.xml");
  ASSERT_NE(m, nullptr);
  EXPECT_EQ(m->nq, 1);
  EXPECT_EQ(m->nsensor, 2);
}

TEST(MujocoEnvTest, MissingFileNamesTheFile) {
  try {
    LoadModel("/nonexistent/dir/robot.xml");
    FAIL() << "expected ModelLoadError";
  } catch (const ModelLoadError& e) {
    EXPECT_NE(std::string(e.what()).find("/nonexistent/dir/robot.xml"), std::string::npos)
        << e.what();
  }
}

TEST(MujocoEnvTest, BrokenModelIsAnErrorNotAnExit) {
  // unknown joint referenced by the actuator: the compiler rejects it
  const std::string xml = R"(<mujoco><worldbody><body><joint name="a"/><geom size="1"/>
      </body></worldbody><actuator><motor joint="nope"/></actuator></mujoco>)";
  try {
    LoadModelFromString(xml);
    FAIL() << "expected ModelLoadError";
  } catch (const ModelLoadError& e) {
    EXPECT_NE(std::string(e.what()).find("nope"), std::string::npos) << e.what();
  }
  // malformed XML
  EXPECT_THROW(LoadModelFromString("<mujoco><worldbody>"), ModelLoadError);
}

TEST(MujocoEnvTest, LibraryErrorThrowsInsteadOfExiting) {
  InstallMujocoHandlers();
  ModelPtr m = LoadModel(kModels + "/pendulum.xml");
  // an invalid state signature makes MuJoCo call mju_error
  try {
    mj_stateSize(m.get(), 1 << 30);
    FAIL() << "expected MujocoError";
  } catch (const MujocoError& e) {
    EXPECT_NE(std::string(e.what()).find("MuJoCo error"), std::string::npos) << e.what();
  }
}

TEST(MujocoEnvTest, ArenaOverflowInsideStepThrowsAndDataRecovers) {
  // 60 boxes dropped in a pile with a tiny arena: the contact/constraint memory runs out
  std::string xml =
      "<mujoco><size memory=\"64K\"/><worldbody><geom type=\"plane\" size=\"5 5 .1\"/>";
  for (int i = 0; i < 60; ++i) {
    xml += "<body pos=\"0 0 " + std::to_string(0.1 + 0.15 * i) +
           "\"><freejoint/><geom type=\"box\" size=\".1 .1 .1\"/></body>";
  }
  xml += "</worldbody></mujoco>";
  ModelPtr m = LoadModelFromString(xml);
  DataPtr d = MakeData(*m);
  std::string message;
  for (int k = 0; k < 2000 && message.empty(); ++k) {
    try {
      mj_step(m.get(), d.get());
    } catch (const MujocoError& e) {
      message = e.what();
    }
  }
  // MuJoCo's out-of-memory error reached us as an exception, the process is still alive
  EXPECT_NE(message.find("memory"), std::string::npos) << "message: '" << message << "'";
  // after a reset the same data steps normally again
  mj_resetData(m.get(), d.get());
  ClearSimulationWarnings(d.get());
  EXPECT_NO_THROW(mj_forward(m.get(), d.get()));
}

TEST(MujocoEnvTest, BadStateIsReportedAsWarning) {
  ModelPtr m = LoadModel(kModels + "/pendulum.xml");
  DataPtr d = MakeData(*m);
  d->qvel[0] = std::numeric_limits<double>::quiet_NaN();
  mj_step(m.get(), d.get());
  const std::string w = SimulationWarnings(*d);
  EXPECT_NE(w.find("bad qvel"), std::string::npos) << "warnings: '" << w << "'";
  // MuJoCo resets the state on a bad qvel; the warning text was captured, not printed
  EXPECT_FALSE(TakeWarningText().empty());
  EXPECT_TRUE(std::isfinite(d->qvel[0]));
  ClearSimulationWarnings(d.get());
  EXPECT_EQ(SimulationWarnings(*d), "");
}

TEST(MujocoEnvTest, VersionIsAtLeastMinimum) {
  const std::string v = MujocoVersion();
  int major = 0, minor = 0;
  ASSERT_EQ(std::sscanf(v.c_str(), "%d.%d", &major, &minor), 2) << v;
  EXPECT_TRUE(major > 3 || (major == 3 && minor >= 11)) << v;
  EXPECT_EQ(mj_version(), mjVERSION_HEADER) << "library and headers differ";
}

}  // namespace
}  // namespace mjsysid
