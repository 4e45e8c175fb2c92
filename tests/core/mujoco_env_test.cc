#include "core/mujoco_env.h"

#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <string>
#include <thread>
#include <vector>

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
  // an invalid state signature makes MuJoCo call mju_error; called directly, outside CallMujoco:
  // the handler's last resort throws through MuJoCo's frames
  try {
    mj_stateSize(m.get(), 1 << 30);
    FAIL() << "expected MujocoError";
  } catch (const MujocoError& e) {
    EXPECT_NE(std::string(e.what()).find("MuJoCo error"), std::string::npos) << e.what();
  }
}

TEST(MujocoEnvTest, CallMujocoTurnsAnErrorIntoAnExceptionFromItsOwnFrame) {
  InstallMujocoHandlers();
  ModelPtr m = LoadModel(kModels + "/pendulum.xml");
  int size = -1;
  // MuJoCo's message, whole; the code after the failing call inside the lambda never runs
  try {
    CallMujoco([&] {
      size = mj_stateSize(m.get(), 1 << 30);
      size = -2;
    });
    FAIL() << "expected MujocoError";
  } catch (const MujocoError& e) {
    EXPECT_EQ(std::string(e.what()),
              "MuJoCo error: mj_stateSize: invalid state signature 1073741824 >= 2^mjNSTATE");
  }
  EXPECT_EQ(size, -1);
  // a successful call returns normally
  CallMujoco([&] { size = mj_stateSize(m.get(), mjSTATE_QPOS); });
  EXPECT_EQ(size, m->nq);
}

TEST(MujocoEnvTest, NestedCallsAndErrorsAfterAJumpLandInTheRightFrame) {
  InstallMujocoHandlers();
  ModelPtr m = LoadModel(kModels + "/pendulum.xml");
  // an inner error is caught by the inner call; the outer call goes on and sees its own error
  std::string inner;
  try {
    CallMujoco([&] {
      try {
        CallMujoco([&] { mj_stateSize(m.get(), -1); });
      } catch (const MujocoError& e) {
        inner = e.what();
      }
      mj_stateSize(m.get(), 1 << 29);
    });
    FAIL() << "expected MujocoError";
  } catch (const MujocoError& e) {
    EXPECT_NE(std::string(e.what()).find("536870912"), std::string::npos) << e.what();
  }
  EXPECT_NE(inner.find("invalid state signature -1 < 0"), std::string::npos) << inner;
  // every call disarmed its target: an error outside any call is the last resort (thrown from the
  // handler), not a jump into a frame that has returned
  EXPECT_THROW(mj_stateSize(m.get(), -3), MujocoError);
}

TEST(MujocoEnvTest, EachThreadGetsItsOwnErrorMessage) {
  InstallMujocoHandlers();
  ModelPtr m = LoadModel(kModels + "/pendulum.xml");
  // four threads raise errors with different messages at the same time, many times each
  std::vector<int> wrong(4, 0), caught(4, 0);
  std::vector<std::thread> threads;
  for (int t = 0; t < 4; ++t) {
    threads.emplace_back([&, t] {
      const int sig = -(t + 1);
      const std::string expected = "invalid state signature " + std::to_string(sig) + " < 0";
      for (int i = 0; i < 2000; ++i) {
        try {
          CallMujoco([&] { mj_stateSize(m.get(), sig); });
        } catch (const MujocoError& e) {
          ++caught[t];
          wrong[t] += std::string(e.what()).find(expected) == std::string::npos;
        }
      }
    });
  }
  for (std::thread& th : threads) th.join();
  for (int t = 0; t < 4; ++t) {
    EXPECT_EQ(caught[t], 2000) << t;
    EXPECT_EQ(wrong[t], 0) << t;
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
      mj_step(m.get(), d.get());  // unwrapped: the last resort, as in the test above
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
