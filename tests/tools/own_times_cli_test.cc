// Sensors and controls at their own times through the real command line (issue 14,
// docs/real-logs.md): a real HDF5 log whose `angle` is logged at 100 Hz (time, sensordata), whose
// `rate` at 250 Hz (sensor_time/rate, sensor_values/rate) and whose controls at 50 Hz
// (ctrl_time), checked and fitted by `sysid`; a broken layout exits 2 naming file, dataset and
// what was expected.
#include <gtest/gtest.h>
#include <hdf5.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cstdio>
#include <filesystem>
#include <random>
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

using test::CliRun;
using test::Sysid;

// writes float64 dataset `name` (rows x cols; 1-D when cols == 0) into `path`, making groups
void AddDataset(const std::string& path, const std::string& name, const double* values,
                hsize_t rows, hsize_t cols) {
  H5Eset_auto2(H5E_DEFAULT, nullptr, nullptr);
  const hid_t f = H5Fopen(path.c_str(), H5F_ACC_RDWR, H5P_DEFAULT);
  ASSERT_GE(f, 0) << path;
  const hid_t lcpl = H5Pcreate(H5P_LINK_CREATE);
  H5Pset_create_intermediate_group(lcpl, 1);
  const hsize_t dims[2] = {rows, cols};
  const hid_t space = H5Screate_simple(cols ? 2 : 1, dims, nullptr);
  const hid_t d =
      H5Dcreate2(f, name.c_str(), H5T_IEEE_F64LE, space, lcpl, H5P_DEFAULT, H5P_DEFAULT);
  ASSERT_GE(d, 0) << name;
  ASSERT_GE(H5Dwrite(d, H5T_NATIVE_DOUBLE, H5S_ALL, H5S_ALL, H5P_DEFAULT, values), 0);
  H5Dclose(d);
  H5Sclose(space);
  H5Pclose(lcpl);
  ASSERT_GE(H5Fclose(f), 0);
}

class OwnTimesCliTest : public ::testing::Test {
 protected:
  // truth: the pendulum with hinge damping 0.12 (the model says 0.05), from its reference state,
  // driven by a multi-sine held for 10 steps (a 50 Hz controller), 1500 steps of 2 ms; noise
  // 1e-3 on both sensors (seed 5). angle kept at every 5th step (100 Hz), rate at every 2nd
  // (250 Hz), the controls at every 10th (50 Hz).
  void SetUp() override {
    dir_ = test::FreshTempDir("own_times");
    ModelPtr m = LoadModel(test::PendulumModelPath());
    const double dt = m->opt.timestep;
    const int T = 1500;
    const RowMatrix u = test::PendulumTorque(*m, T, 10);
    const RowMatrix y = test::MeasurePendulum(*m, InitialState(), u);
    const int angle = test::SensorColumn(*m, "angle");
    const int rate = test::SensorColumn(*m, "rate");
    io::Sequence s;
    s.name = "run1";
    s.actuator_names = {"torque"};
    s.sensor_names = {"angle"};
    s.sensor_dims = {1};
    s.time.resize(T / 5);
    s.sensordata.resize(T / 5, 1);
    for (int j = 0; j < T / 5; ++j) {
      s.time[j] = (5 * j) * dt;
      s.sensordata(j, 0) = y(5 * j, angle);
    }
    test::SetControlsEvery(u, dt, 10, &s);
    io::Log log;
    log.sequences.push_back(s);
    log_ = dir_ + "/robot.h5";
    io::WriteLog(log_, log);
    Eigen::VectorXd rate_time(T / 2);
    Eigen::VectorXd rate_values(T / 2);
    for (int j = 0; j < T / 2; ++j) {
      rate_time[j] = (2 * j) * dt;
      rate_values[j] = y(2 * j, rate);
    }
    AddDataset(log_, "/run1/sensor_time/rate", rate_time.data(), T / 2, 0);
    AddDataset(log_, "/run1/sensor_values/rate", rate_values.data(), T / 2, 1);
  }
  void TearDown() override { fs::remove_all(dir_); }

  // fits the hinge damping from 0.05 with sigmas equal to the noise
  std::string Experiment(const std::string& data) {
    const std::string path = dir_ + "/fit.yaml";
    test::WriteFile(path, test::PendulumDampingYaml(data));
    return path;
  }

  std::string dir_, log_;
};

// truth 0.12, start 0.05, noise 1e-3: exit 0, no time-base warning (each time dataset is
// regular), the estimate within 0.5 % of the truth
TEST_F(OwnTimesCliTest, FitsSensorsAndControlsAtTheirOwnRates) {
  const std::string exp = Experiment(log_);
  const CliRun check = Sysid("check --no-jacobians " + exp);
  EXPECT_EQ(check.code, 0) << check.output;
  EXPECT_EQ(check.output.find("varies by more than"), std::string::npos) << check.output;
  const CliRun fit = Sysid("fit " + exp + " --out " + dir_ + "/out --quiet");
  ASSERT_EQ(fit.code, 0) << fit.output;
  const std::string result = test::ReadFile(dir_ + "/out/result.yaml");
  const size_t at = result.find("name: damping");
  ASSERT_NE(at, std::string::npos) << result;
  const size_t v = result.find("value: ", at);
  ASSERT_NE(v, std::string::npos);
  const double value = std::stod(result.substr(v + 7));
  std::printf("[ measured ] damping %.6g (truth 0.12)\n", value);
  EXPECT_NEAR(value, 0.12, 0.0006);
  // each sensor is masked at the other's times: 300 angle + 750 rate samples on 1050 - 150
  // shared times (every 10th step has both)
  EXPECT_NE(result.find("600 of 900 values not measured"), std::string::npos) << result;
  EXPECT_NE(result.find("150 of 900 values not measured"), std::string::npos) << result;
}

TEST_F(OwnTimesCliTest, ValuesWithoutTimesExitTwoNamingTheDataset) {
  H5Eset_auto2(H5E_DEFAULT, nullptr, nullptr);
  const hid_t f = H5Fopen(log_.c_str(), H5F_ACC_RDWR, H5P_DEFAULT);
  ASSERT_GE(f, 0);
  ASSERT_GE(H5Ldelete(f, "/run1/sensor_time/rate", H5P_DEFAULT), 0);
  ASSERT_GE(H5Fclose(f), 0);
  const CliRun check = Sysid("check --no-jacobians " + Experiment(log_));
  EXPECT_EQ(check.code, 2) << check.output;
  for (const std::string& piece : {log_, std::string("/run1/sensor_values/rate"),
                                   std::string("has no times: expected dataset "
                                               "/run1/sensor_time/rate (Ts)")}) {
    EXPECT_NE(check.output.find(piece), std::string::npos) << piece << "\n" << check.output;
  }
}

}  // namespace
}  // namespace mjsysid
