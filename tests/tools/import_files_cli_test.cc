// `sysid import` of one sequence from several CSV files at their own rates, through the real
// command line (issue 14, docs/cli.md): the pendulum's commands at 50 Hz in controls.csv, `angle`
// at 100 Hz (with empty cells) in angle.csv, `rate` at 250 Hz in rate.csv, imported as
// `run1=controls.csv+angle.csv+rate.csv`, read back, then fitted by `sysid fit`; a second file
// with actuator columns exits 2 naming it.
#include <gtest/gtest.h>
#include <unistd.h>

#include <cmath>
#include <cstdio>
#include <filesystem>
#include <string>

#include "core/mujoco_env.h"
#include "sysid/io/log.h"
#include "tests/cli_util.h"
#include "tests/file_util.h"
#include "tests/log_builder.h"
#include "tests/test_util.h"

namespace mjsysid {
namespace {

namespace fs = std::filesystem;
using test::Sysid;

class ImportFilesCliTest : public ::testing::Test {
 protected:
  // truth: hinge damping 0.12 (the model says 0.05), from the reference state, a multi-sine held
  // for 10 steps (a 50 Hz controller), 1500 steps of 2 ms, noise 1e-3 (seed 5); angle every 5th
  // step (100 Hz, every 37th of its rows empty), rate every 2nd (250 Hz), controls every 10th
  void SetUp() override {
    dir_ = test::FreshTempDir("import_files");
    ModelPtr m = LoadModel(test::PendulumModelPath());
    const double dt = m->opt.timestep;
    const int T = 1500;
    const RowMatrix u = test::PendulumTorque(*m, T, 10);
    const RowMatrix y = test::MeasurePendulum(*m, InitialState(), u);
    const int angle = test::SensorColumn(*m, "angle");
    const int rate = test::SensorColumn(*m, "rate");
    auto row = [](double t, const std::string& v) {
      char buf[64];
      std::snprintf(buf, sizeof(buf), "%.6f,", t);
      return buf + v + "\n";
    };
    auto num = [](double v) {
      char buf[32];
      std::snprintf(buf, sizeof(buf), "%.17g", v);
      return std::string(buf);
    };
    std::string controls = "time,torque\n", angles = "time,angle\n", rates = "time,rate\n";
    for (int k = 0; k < T; ++k) {
      if (k % 10 == 0) controls += row(k * dt, num(u(k, 0)));
      if (k % 5 == 0) angles += row(k * dt, (k / 5) % 37 == 36 ? "" : num(y(k, angle)));
      if (k % 2 == 0) rates += row(k * dt, num(y(k, rate)));
    }
    test::WriteFile(dir_ + "/controls.csv", controls);
    test::WriteFile(dir_ + "/angle.csv", angles);
    test::WriteFile(dir_ + "/rate.csv", rates);
  }
  void TearDown() override { fs::remove_all(dir_); }

  std::string dir_;
};

// the union of the sensor times (300 + 750 - 150 shared = 900), the controls at their 150 times,
// each sensor NaN where its file has no row (and at angle's 8 empty cells); then fitted: exit 0,
// damping within 0.5 % of the truth
TEST_F(ImportFilesCliTest, ImportsOneSequenceFromFilesAtTheirOwnRates) {
  const std::string log = dir_ + "/robot.h5";
  const test::CliRun run =
      Sysid("import " + test::PendulumModelPath() + " run1=" + dir_ + "/controls.csv+" + dir_ +
            "/angle.csv+" + dir_ + "/rate.csv --out " + log);
  ASSERT_EQ(run.code, 0) << run.output;
  const io::Log read = io::ReadLog(log);
  ASSERT_EQ(read.sequences.size(), 1u);
  const io::Sequence& s = read.sequences[0];
  EXPECT_EQ(s.name, "run1");
  EXPECT_EQ(s.time.size(), 900);
  EXPECT_EQ(s.ctrl_time.size(), 150);
  EXPECT_EQ(s.ctrl.rows(), 150);
  ASSERT_EQ(s.sensor_names, (std::vector<std::string>{"angle", "rate"}));
  EXPECT_EQ(s.sensordata.col(0).array().isNaN().count(), 600 + 8);
  EXPECT_EQ(s.sensordata.col(1).array().isNaN().count(), 150);

  const std::string exp = dir_ + "/fit.yaml";
  test::WriteFile(exp, test::PendulumDampingYaml(log));
  const test::CliRun fit = Sysid("fit " + exp + " --out " + dir_ + "/out --quiet");
  ASSERT_EQ(fit.code, 0) << fit.output;
  const std::string result = test::ReadFile(dir_ + "/out/result.yaml");
  const size_t at = result.find("name: damping");
  ASSERT_NE(at, std::string::npos) << result;
  const double value = std::stod(result.substr(result.find("value: ", at) + 7));
  std::printf("[ measured ] damping %.6g (truth 0.12)\n", value);
  EXPECT_NEAR(value, 0.12, 0.0006);
}

// controls in two files, a sensor in two files: exit 2 naming the file
TEST_F(ImportFilesCliTest, AmbiguousFilesExitTwoNamingTheFile) {
  test::WriteFile(dir_ + "/more.csv", "time,torque,rate\n0,1,0.5\n0.1,1,0.5\n");
  const test::CliRun two = Sysid("import " + test::PendulumModelPath() + " " + dir_ +
                                 "/controls.csv+" + dir_ + "/more.csv --out " + dir_ + "/x.h5");
  EXPECT_EQ(two.code, 2) << two.output;
  EXPECT_NE(two.output.find(dir_ + "/more.csv: has actuator columns, and so has"),
            std::string::npos)
      << two.output;
  test::WriteFile(dir_ + "/rate2.csv", "time,rate\n0,0.5\n0.1,0.5\n");
  const test::CliRun twice =
      Sysid("import " + test::PendulumModelPath() + " " + dir_ + "/controls.csv+" + dir_ +
            "/rate.csv+" + dir_ + "/rate2.csv --out " + dir_ + "/x.h5");
  EXPECT_EQ(twice.code, 2) << twice.output;
  EXPECT_NE(twice.output.find("sensor 'rate' is in"), std::string::npos) << twice.output;
}

}  // namespace
}  // namespace mjsysid
