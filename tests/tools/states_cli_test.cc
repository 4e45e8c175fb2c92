// Logged states as fitted data through the real command line (`sysid fit`, experiment key
// `states`, docs/experiment-schema.md): a model without sensors fitted from a real HDF5 log of its
// qpos and qvel, and the key's errors (exit 2, naming file, line and what was expected).
#include <gtest/gtest.h>
#include <sys/wait.h>

#include <cstdio>
#include <filesystem>
#include <random>
#include <string>

#include "core/mujoco_env.h"
#include "core/simulator.h"
#include "sysid/io/log.h"
#include "sysid/io/result.h"
#include "tests/cli_util.h"
#include "tests/file_util.h"
#include "tests/test_util.h"

namespace mjsysid {
namespace {

namespace fs = std::filesystem;

using test::CliRun;
using test::Sysid;

class StatesCliTest : public ::testing::Test {
 protected:
  // the model file and a log of 800 samples at 500 Hz with truth damping 0.35 on hinge1 (the
  // model says 0.2), states only: qpos with noise 1e-3 rad, qvel with 1e-2 rad/s (seed 11)
  void SetUp() override {
    dir_ = test::FreshTempDir("states_cli");
    test::WriteFile(dir_ + "/chain.xml", test::kChainXml);
    ModelPtr m = LoadModelFromString(test::kChainXml);
    const int T = 800;
    Simulator sim(*m, {test::Spec("joint_damping", "hinge1")});
    sim.SetParameters(Eigen::VectorXd::Constant(1, 0.35));
    InitialState x0;
    x0.qpos = Eigen::Vector2d(0.4, -0.3);
    const RowMatrix u = test::Excitation(*m, T, 2.0, 3);
    const Trajectory tr = sim.Rollout(SequenceInput{x0, u});
    io::Sequence s;
    s.name = "run1";
    s.time = Eigen::VectorXd::LinSpaced(T, 0, (T - 1) * m->opt.timestep);
    s.ctrl = u;
    s.actuator_names = {"torque1"};
    s.sensordata.resize(T, 0);
    s.qpos = tr.states.topRows(T).leftCols(2);
    s.qvel = tr.states.topRows(T).middleCols(2, 2);
    std::mt19937_64 rng(11);
    std::normal_distribution<double> n01(0, 1);
    for (Eigen::Index i = 0; i < s.qpos.size(); ++i) s.qpos.data()[i] += 1e-3 * n01(rng);
    for (Eigen::Index i = 0; i < s.qvel.size(); ++i) s.qvel.data()[i] += 1e-2 * n01(rng);
    io::Log log;
    log.sequences.push_back(s);
    io::WriteLog(dir_ + "/log.h5", log);
    s.qpos.resize(0, 0);
    log.sequences[0] = s;
    io::WriteLog(dir_ + "/no_qpos.h5", log);
  }
  void TearDown() override { fs::remove_all(dir_); }

  // an experiment fitting hinge1's damping from start 0.1 with the given `states` block
  std::string Experiment(const std::string& name, const std::string& states,
                         const std::string& data = "log.h5") {
    const std::string path = dir_ + "/" + name + ".yaml";
    test::WriteFile(path, "model: chain.xml\ndata: " + data +
                              "\nparameters:\n"
                              "  - {name: damping, target: joint_damping, object: hinge1, "
                              "initial: 0.1, bounds: [0.001, 10], transform: log}\n" +
                              states);
    return path;
  }

  std::string dir_;
};

// truth 0.35, start 0.1, noise 1e-3 / 1e-2 (the sigmas given): exit 0, converged, the estimate
// within 1 % of the truth. The initial state is estimated: the log's first row carries the noise
// too (from it, the fit ends in model_mismatch: chi-square ratio 5.1, measured)
TEST_F(StatesCliTest, FitsAModelWithoutSensorsFromItsStates) {
  const std::string exp =
      Experiment("fit",
                 "initial_state: {estimate: true}\n"
                 "states:\n"
                 "  qpos: {sigma: 1.0e-3}\n"
                 "  qvel: {sigma: [1.0e-2, 1.0e-2], joints: [hinge1, hinge2]}\n");
  const CliRun check = Sysid("check " + exp);
  EXPECT_EQ(check.code, 0) << check.output;
  const CliRun fit = Sysid("fit " + exp + " --out " + dir_ + "/out --quiet");
  std::printf("%s\n", fit.output.c_str());
  ASSERT_EQ(fit.code, 0) << fit.output;
  EXPECT_NE(fit.output.find("converged"), std::string::npos) << fit.output;
  const std::string result = test::ReadFile(dir_ + "/out/result.yaml");
  const size_t at = result.find("name: damping");
  ASSERT_NE(at, std::string::npos) << result;
  const size_t v = result.find("value: ", at);
  ASSERT_NE(v, std::string::npos);
  const double value = std::stod(result.substr(v + 7));
  std::printf("[ measured ] damping %.6g (truth 0.35)\n", value);
  EXPECT_NEAR(value, 0.35, 0.0035);
  EXPECT_NE(result.find("status: converged"), std::string::npos) << result;
  // result.h5 keeps the fitted state columns (read back), and the report plots them
  const io::FitResultFile back = io::ReadResult(dir_ + "/out");
  ASSERT_EQ(back.sequences.size(), 1u);
  const SequenceResult& sr = back.sequences[0];
  EXPECT_EQ(sr.state_names,
            (std::vector<std::string>{"qpos:hinge1", "qpos:hinge2", "qvel:hinge1", "qvel:hinge2"}));
  EXPECT_EQ(sr.state_measured.rows(), 800);
  EXPECT_EQ(sr.state_simulated_final.cols(), 4);
  EXPECT_EQ(sr.state_residual_final.cols(), 4);
  // the fitted qpos within 5 sigma of the logged one at every sample
  EXPECT_LE((sr.state_measured.col(0) - sr.state_simulated_final.col(0)).cwiseAbs().maxCoeff(),
            5e-3);
  const CliRun report = Sysid("report " + dir_ + "/out");
  EXPECT_EQ(report.code, 0) << report.output;
  EXPECT_TRUE(fs::exists(dir_ + "/out/report.html"));
}

// a model with sensors (the double pendulum: jointpos/jointvel of the same joints, hinge2's
// damping 0.02 where the log's is 0.1) and a log of states only: no sensor is fitted (none is
// logged), the states are. Both dampings fitted from 0.1 and 0.05: exit 0, converged, hinge1's
// within 1 % of 0.35
TEST_F(StatesCliTest, ModelWithSensorsFitsALogOfStatesOnly) {
  const std::string exp = dir_ + "/dp.yaml";
  test::WriteFile(exp, "model: " + std::string(MJSYSID_MODELS_DIR) +
                           "/double_pendulum.xml\ndata: log.h5\n"
                           "parameters:\n"
                           "  - {name: damping, target: joint_damping, object: hinge1, "
                           "initial: 0.1, bounds: [0.001, 10], transform: log}\n"
                           "  - {name: damping2, target: joint_damping, object: hinge2, "
                           "initial: 0.05, bounds: [0.001, 10], transform: log}\n"
                           "initial_state: {estimate: true}\n"
                           "states:\n  qpos: {sigma: 1.0e-3}\n  qvel: {sigma: 1.0e-2}\n");
  const CliRun fit = Sysid("fit " + exp + " --out " + dir_ + "/out_dp --quiet");
  std::printf("%s\n", fit.output.c_str());
  EXPECT_EQ(fit.code, 0) << fit.output;
  const io::FitResultFile back = io::ReadResult(dir_ + "/out_dp");
  ASSERT_EQ(back.parameters.size(), 2u);
  EXPECT_NEAR(back.parameters[0].value, 0.35, 0.0035);
  EXPECT_TRUE(back.sequences[0].sensor_names.empty());
}

// the key's errors: exit 2 with file:line:column and what was expected
TEST_F(StatesCliTest, BadStatesKeyExitsWithTwo) {
  struct Case {
    std::string states, data, expected;
  };
  const Case cases[] = {
      {"states:\n  qpos: {sigma: 1.0e-3, joints: [hinge1, hinge3]}\n", "log.h5",
       "unknown.yaml:6:42: no joint named 'hinge3'"},
      {"states:\n  qpos: {sigma: 0}\n", "log.h5",
       "sigma.yaml:6:17: states.qpos.sigma: must be > 0"},
      {"states:\n  qpos: {joints: [hinge1]}\n", "log.h5",
       "missing required key 'sigma' in states.qpos"},
      {"states:\n  qvel: {sigma: [1, 2], joints: [hinge1]}\n", "log.h5",
       "has 2 values for 1 joints"},
      {"states:\n  qpos: {sigma: 1.0e-3}\n", "no_qpos.h5",
       "states.qpos is fitted but " + dir_ + "/no_qpos.h5: /run1 has no qpos dataset"},
  };
  const char* names[] = {"unknown", "sigma", "required", "count", "no_qpos"};
  for (size_t i = 0; i < 5; ++i) {
    const std::string exp = Experiment(names[i], cases[i].states, cases[i].data);
    const CliRun r = Sysid("fit " + exp + " --out " + dir_ + "/out_" + names[i] + " --quiet");
    EXPECT_EQ(r.code, 2) << names[i] << ": " << r.output;
    EXPECT_NE(r.output.find(cases[i].expected), std::string::npos) << names[i] << ": " << r.output;
  }
}

}  // namespace
}  // namespace mjsysid
