// NaN (not measured) cells in logged qpos/qvel through the real command line (issue 14,
// docs/real-logs.md): a pendulum log whose states have NaN cells is read, its states fitted as
// data with the NaN cells masked and counted; a NaN initial state exits 2 naming file, dataset
// and row unless the initial state is estimated; a window starting at a NaN row estimates its own.
#include <gtest/gtest.h>
#include <unistd.h>

#include <cmath>
#include <cstdio>
#include <filesystem>
#include <limits>
#include <string>

#include "core/mujoco_env.h"
#include "core/simulator.h"
#include "sysid/io/log.h"
#include "tests/cli_util.h"
#include "tests/file_util.h"
#include "tests/log_builder.h"
#include "tests/test_util.h"

namespace mjsysid {
namespace {

namespace fs = std::filesystem;
using test::Sysid;

const double kNan = std::numeric_limits<double>::quiet_NaN();

class NanStatesCliTest : public ::testing::Test {
 protected:
  // truth: hinge damping 0.12 (the model says 0.05), from qpos 0.3, a multi-sine, 1000 steps of
  // 2 ms, every step logged: sensors with noise 1e-3 (seed 5), qpos and qvel exact except NaN in
  // qpos at every 50th row from row 25 (20 cells) and in qvel at rows 100..104 (5 cells)
  void SetUp() override {
    dir_ = test::FreshTempDir("nan_states");
    ModelPtr m = LoadModel(test::PendulumModelPath());
    const double dt = m->opt.timestep;
    const int T = 1000;
    const RowMatrix u = test::PendulumTorque(*m, T);
    InitialState x0;
    x0.qpos = Eigen::VectorXd::Constant(1, 0.3);
    x0.qvel = Eigen::VectorXd::Zero(1);
    const std::vector<test::Truth> truth = test::PendulumTruth();
    const RowMatrix y = test::MeasurePendulum(*m, x0, u);
    Simulator sim(*m, {truth[0].spec});
    sim.SetParameters(Eigen::VectorXd::Constant(1, 0.12));
    const Trajectory tr = sim.Rollout(SequenceInput{x0, u});
    seq_.name = "run1";
    seq_.actuator_names = {"torque"};
    seq_.sensor_names = {"angle", "rate"};
    seq_.sensor_dims = {1, 1};
    seq_.time.resize(T);
    for (int k = 0; k < T; ++k) seq_.time[k] = k * dt;
    seq_.ctrl = u;
    seq_.sensordata = y;
    seq_.qpos = tr.states.topRows(T).leftCols(1);
    seq_.qvel = tr.states.topRows(T).middleCols(1, 1);
    for (int k = 25; k < T; k += 50) seq_.qpos(k, 0) = kNan;
    for (int k = 100; k < 105; ++k) seq_.qvel(k, 0) = kNan;
  }
  void TearDown() override { fs::remove_all(dir_); }

  std::string WriteExperiment(const io::Sequence& s, const std::string& extra) {
    io::Log log;
    log.sequences.push_back(s);
    io::WriteLog(dir_ + "/log.h5", log);
    const std::string path = dir_ + "/fit.yaml";
    test::WriteFile(path, test::PendulumDampingYaml(dir_ + "/log.h5") +
                              "states:\n  qpos: {sigma: 1.0e-3}\n  qvel: {sigma: 1.0e-2}\n" +
                              extra);
    return path;
  }

  std::string dir_;
  io::Sequence seq_;
};

// read back with the NaN cells; fitted: exit 0, damping within 1 % of the truth, the masked state
// cells counted in the warnings
TEST_F(NanStatesCliTest, NanStateCellsAreMaskedAndCounted) {
  const std::string exp = WriteExperiment(seq_, "");
  const io::Log read = io::ReadLog(dir_ + "/log.h5");
  EXPECT_EQ(read.sequences[0].qpos.array().isNaN().count(), 20);
  const test::CliRun fit = Sysid("fit " + exp + " --out " + dir_ + "/out --quiet");
  ASSERT_EQ(fit.code, 0) << fit.output;
  const std::string result = test::ReadFile(dir_ + "/out/result.yaml");
  const size_t at = result.find("name: damping");
  ASSERT_NE(at, std::string::npos) << result;
  const double value = std::stod(result.substr(result.find("value: ", at) + 7));
  std::printf("[ measured ] damping %.6g (truth 0.12)\n", value);
  EXPECT_NEAR(value, 0.12, 0.0012);
  EXPECT_NE(result.find("state 'qpos:hinge': 20 of 1000 samples not measured"), std::string::npos)
      << result;
  EXPECT_NE(result.find("state 'qvel:hinge': 5 of 1000 samples not measured"), std::string::npos)
      << result;
}

// a NaN in the initial state: exit 2 naming the file, the dataset and row 0; with the initial
// state estimated the fit runs (exit 0) and warns
TEST_F(NanStatesCliTest, NanInitialStateIsAnErrorUnlessEstimated) {
  io::Sequence s = seq_;
  s.qpos(0, 0) = kNan;
  const std::string exp = WriteExperiment(s, "");
  const test::CliRun fit = Sysid("fit " + exp + " --out " + dir_ + "/out --quiet");
  EXPECT_EQ(fit.code, 2) << fit.output;
  EXPECT_NE(fit.output.find(dir_ + "/log.h5: /run1/qpos: row 0"), std::string::npos) << fit.output;
  EXPECT_NE(fit.output.find("not measured (NaN in column 0)"), std::string::npos) << fit.output;
  const std::string estimated = WriteExperiment(s, "initial_state: {estimate: true}\n");
  const test::CliRun ok = Sysid("fit " + estimated + " --out " + dir_ + "/out2 --quiet");
  EXPECT_EQ(ok.code, 0) << ok.output;
  EXPECT_NE(test::ReadFile(dir_ + "/out2/result.yaml").find("row 0 has NaN (not measured)"),
            std::string::npos);
}

// a window starting at a row with a NaN state (row 25, t = 0.05 s): its initial state is estimated
// (as a window without logged states), exit 0, warned
TEST_F(NanStatesCliTest, WindowStartingAtANanRowEstimatesItsState) {
  const std::string exp =
      WriteExperiment(seq_, "sequences:\n  - {name: run1, start: 0.05, end: 1.5}\n");
  const test::CliRun fit = Sysid("fit " + exp + " --out " + dir_ + "/out --quiet");
  ASSERT_EQ(fit.code, 0) << fit.output;
  EXPECT_NE(test::ReadFile(dir_ + "/out/result.yaml").find("row 0 of the window has NaN"),
            std::string::npos);
}

}  // namespace
}  // namespace mjsysid
