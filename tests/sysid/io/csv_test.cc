#include "sysid/io/csv.h"

#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <functional>
#include <initializer_list>
#include <string>
#include <vector>

#include "core/mujoco_env.h"
#include "sysid/io/log.h"
#include "tests/temp_dir_test.h"

namespace mjsysid::io {
namespace {

namespace fs = std::filesystem;
const std::string kModels = MJSYSID_MODELS_DIR;

// a fresh directory per test, the pendulum and the box models
class CsvTest : public test::TempDirTest {
 protected:
  void SetUp() override {
    TempDirTest::SetUp();
    pendulum_ = LoadModel(kModels + "/pendulum.xml");
    box_ = LoadModel(kModels + "/box_floor.xml");
  }

  // writes `text` to a file in the test directory and returns its path
  std::string Write(const std::string& name, const std::string& text) const {
    const std::string path = (dir_ / name).string();
    std::ofstream(path, std::ios::binary) << text;
    return path;
  }

  // the LogError message of importing `text` for the pendulum; fails the test otherwise
  std::string PendulumError(const std::string& text, std::string* path_out = nullptr) const {
    const std::string path = Write("data.csv", text);
    if (path_out) *path_out = path;
    try {
      ImportCsv(path, *pendulum_, "run");
    } catch (const LogError& e) {
      return e.what();
    }
    ADD_FAILURE() << "expected LogError for:\n" << text;
    return "";
  }

  ModelPtr pendulum_;
  ModelPtr box_;
};

void ExpectMentions(const std::string& message, std::initializer_list<std::string> pieces) {
  for (const std::string& piece : pieces) {
    EXPECT_NE(message.find(piece), std::string::npos)
        << "message lacks \"" << piece << "\": " << message;
  }
}

// ---------------------------------------------------------------------------------------------
// happy paths

// Several files of one sequence (ImportCsvFiles): the controls file (with `angle` too) at its
// times, `rate` at its own; sample times the union of both files' times (0, 0.01, 0.02 and
// 0.015, 0.025 merged), each sensor NaN where its file has no row, the controls at their times
TEST_F(CsvTest, SeveralFilesMergeOntoTheUnionOfTheirTimes) {
  const std::string controls = Write("c.csv", "time,torque,angle\n0,1,0.1\n0.01,2,\n0.02,3,0.3\n");
  const std::string rates = Write("r.csv", "time,rate\n0.01,5\n0.015,6\n0.025,7\n");
  const Sequence s = ImportCsvFiles({controls, rates}, *pendulum_, "run");
  ASSERT_EQ(s.time.size(), 5);
  EXPECT_EQ(s.time[3], 0.02);
  EXPECT_EQ(s.ctrl_time.size(), 3);
  EXPECT_EQ(s.ctrl(2, 0), 3.0);
  ASSERT_EQ(s.sensor_names, (std::vector<std::string>{"angle", "rate"}));
  // angle: 0.1 at 0, NaN at 0.01 (empty cell), 0.015, 0.025; rate: 5 at 0.01, 6 at 0.015
  EXPECT_EQ(s.sensordata(0, 0), 0.1);
  EXPECT_TRUE(std::isnan(s.sensordata(1, 0)));
  EXPECT_EQ(s.sensordata(1, 1), 5.0);
  EXPECT_EQ(s.sensordata(2, 1), 6.0);
  EXPECT_TRUE(std::isnan(s.sensordata(3, 1)));
  EXPECT_EQ(s.sensordata(3, 0), 0.3);
  EXPECT_EQ(s.sensordata.array().isNaN().count(), 5);
  // states in a file of several: an error naming the file
  const std::string states = Write("q.csv", "time,rate,qpos[0]\n0,1,0\n0.01,1,0\n");
  try {
    ImportCsvFiles({controls, states}, *pendulum_, "run");
    ADD_FAILURE() << "expected LogError";
  } catch (const LogError& e) {
    ExpectMentions(e.what(), {states, "state columns"});
  }
}

TEST_F(CsvTest, PendulumColumnsInAnyOrder) {
  // shuffled columns, spaces, a quoted header, CRLF, a blank line, a byte order mark
  const std::string path = Write("p.csv",
                                 "\xEF\xBB\xBF"
                                 "rate, time ,qvel[0],\"torque\",angle,qpos[0]\r\n"
                                 "0.5,0,1.5,-2,0.25,0.125\r\n"
                                 "\r\n"
                                 "-0.5, 0.002 ,2.5e-3,+3,1e-310,7\r\n");
  const Sequence s = ImportCsv(path, *pendulum_, "run");
  EXPECT_EQ(s.name, "run");
  ASSERT_EQ(s.time.size(), 2);
  EXPECT_EQ(s.time[0], 0.0);
  EXPECT_EQ(s.time[1], 0.002);
  ASSERT_EQ(s.ctrl.rows(), 2);
  ASSERT_EQ(s.ctrl.cols(), 1);
  EXPECT_EQ(s.ctrl(0, 0), -2.0);
  EXPECT_EQ(s.ctrl(1, 0), 3.0);
  EXPECT_EQ(s.actuator_names, std::vector<std::string>{"torque"});
  // sensors in model order: angle, rate
  EXPECT_EQ(s.sensor_names, (std::vector<std::string>{"angle", "rate"}));
  EXPECT_EQ(s.sensor_dims, (std::vector<int>{1, 1}));
  ASSERT_EQ(s.sensordata.cols(), 2);
  EXPECT_EQ(s.sensordata(0, 0), 0.25);
  EXPECT_EQ(s.sensordata(0, 1), 0.5);
  EXPECT_EQ(s.sensordata(1, 0), 1e-310);
  EXPECT_EQ(s.sensordata(1, 1), -0.5);
  ASSERT_EQ(s.qpos.cols(), 1);
  EXPECT_EQ(s.qpos(1, 0), 7.0);
  ASSERT_EQ(s.qvel.cols(), 1);
  EXPECT_EQ(s.qvel(1, 0), 2.5e-3);
  EXPECT_EQ(s.act.rows(), 0);
}

TEST_F(CsvTest, MissingSensorsAreLeftOut) {
  const std::string path = Write("p.csv", "time,torque,rate\n0,1,2\n0.002,3,4\n");
  const Sequence s = ImportCsv(path, *pendulum_, "run");
  EXPECT_EQ(s.sensor_names, std::vector<std::string>{"rate"});
  EXPECT_EQ(s.sensor_dims, std::vector<int>{1});
  ASSERT_EQ(s.sensordata.cols(), 1);
  EXPECT_EQ(s.sensordata(1, 0), 4.0);
  EXPECT_EQ(s.qpos.rows(), 0);
  EXPECT_EQ(s.qvel.rows(), 0);
}

// sensors at their own times in one file: each row holds what was sampled at its time, the other
// cells empty (or NaN): values not measured, NaN in the sequence
TEST_F(CsvTest, EmptySensorAndControlCellsAreNotMeasured) {
  const std::string path =
      Write("p.csv", "time,torque,angle,rate\n0,1,0.1,\n0.0013,,,2\n0.004,3,NaN,4\n");
  const Sequence s = ImportCsv(path, *pendulum_, "run");
  ASSERT_EQ(s.sensordata.rows(), 3);
  EXPECT_EQ(s.sensordata(0, 0), 0.1);
  EXPECT_TRUE(std::isnan(s.sensordata(0, 1)));
  EXPECT_TRUE(std::isnan(s.sensordata(1, 0)));
  EXPECT_EQ(s.sensordata(1, 1), 2.0);
  EXPECT_TRUE(std::isnan(s.sensordata(2, 0)));
  EXPECT_TRUE(std::isnan(s.ctrl(1, 0)));
  EXPECT_EQ(s.time[1], 0.0013);
}

TEST_F(CsvTest, MultiDimensionalSensors) {
  // box_vel components shuffled, box_quat left out, full qvel
  std::string text =
      "box_vel[2],time,box_pos[0],box_pos[1],box_pos[2],push_x,box_vel[0],box_vel[1]";
  for (int i = 0; i < 6; ++i) text += ",qvel[" + std::to_string(i) + "]";
  text += "\n";
  for (int k = 0; k < 3; ++k) {
    const double base = 10.0 * k;
    text += std::to_string(base + 5) + "," + std::to_string(0.004 * k) + ",";
    text += std::to_string(base + 0) + "," + std::to_string(base + 1) + "," +
            std::to_string(base + 2) + ",";
    text += std::to_string(-k) + "," + std::to_string(base + 3) + "," + std::to_string(base + 4);
    for (int i = 0; i < 6; ++i) text += "," + std::to_string(100 * k + i);
    text += "\n";
  }
  const std::string path = Write("box.csv", text);
  const Sequence s = ImportCsv(path, *box_, "push");
  EXPECT_EQ(s.sensor_names, (std::vector<std::string>{"box_pos", "box_vel"}));
  EXPECT_EQ(s.sensor_dims, (std::vector<int>{3, 3}));
  ASSERT_EQ(s.sensordata.rows(), 3);
  ASSERT_EQ(s.sensordata.cols(), 6);
  // box_pos then box_vel, components in order: 10k + 0..5
  for (int k = 0; k < 3; ++k) {
    for (int c = 0; c < 6; ++c) EXPECT_EQ(s.sensordata(k, c), 10.0 * k + c) << k << "," << c;
  }
  EXPECT_EQ(s.ctrl(2, 0), -2.0);
  ASSERT_EQ(s.qvel.cols(), 6);
  EXPECT_EQ(s.qvel(2, 5), 205.0);
  EXPECT_EQ(s.qpos.rows(), 0);
}

TEST_F(CsvTest, ImportedSequenceRoundTripsAndValidates) {
  std::string text = "time,torque,angle,rate,qpos[0],qvel[0]\n";
  for (int k = 0; k < 10; ++k) {
    text += std::to_string(0.004 * k) + ",0.1,0.2,0.3,0.2,0.3\n";
  }
  const std::string path = Write("p.csv", text);
  Log log;
  log.sequences.push_back(ImportCsv(path, *pendulum_, "csv run"));
  EXPECT_NO_THROW(ValidateLogAgainstModel(log, *pendulum_, path));
  const std::string h5 = (dir_ / "p.h5").string();
  WriteLog(h5, log);
  const Log back = ReadLog(h5);
  ASSERT_EQ(back.sequences.size(), 1u);
  EXPECT_EQ(back.sequences[0].name, "csv run");
  EXPECT_EQ(back.sequences[0].time, log.sequences[0].time);
  EXPECT_EQ(back.sequences[0].sensordata, log.sequences[0].sensordata);
  EXPECT_EQ(back.sequences[0].qvel, log.sequences[0].qvel);
}

// ---------------------------------------------------------------------------------------------
// errors

TEST_F(CsvTest, UnknownColumnNamesHeaderAndHint) {
  std::string path;
  const std::string msg = PendulumError("time,torque,angel\n0,1,2\n", &path);
  ExpectMentions(msg, {path, ":1", "column 3", "'angel'", "did you mean 'angle'",
                       "valid columns: time, torque, angle, rate, qpos[0], qvel[0]"});
}

TEST_F(CsvTest, MultiDimensionalSensorNeedsIndices) {
  const std::string path = Write("box.csv", "time,push_x,box_pos\n0,1,2\n");
  try {
    ImportCsv(path, *box_, "run");
    FAIL() << "expected LogError";
  } catch (const LogError& e) {
    ExpectMentions(e.what(), {path, "'box_pos'", "box_pos[0..2]", "box_quat[0..3]"});
  }
}

TEST_F(CsvTest, PartialSensorComponents) {
  const std::string path = Write("box.csv", "time,push_x,box_pos[0],box_pos[2]\n0,1,2,3\n");
  try {
    ImportCsv(path, *box_, "run");
    FAIL() << "expected LogError";
  } catch (const LogError& e) {
    ExpectMentions(e.what(), {path, "'box_pos'", "'box_pos[1]'", "missing"});
  }
}

TEST_F(CsvTest, PartialStateComponents) {
  const std::string path = Write("box.csv", "time,push_x,qpos[0],qpos[1]\n0,1,2,3\n");
  try {
    ImportCsv(path, *box_, "run");
    FAIL() << "expected LogError";
  } catch (const LogError& e) {
    ExpectMentions(e.what(), {path, "'qpos[2]'", "all 7"});
  }
}

TEST_F(CsvTest, StateIndexOutOfRange) {
  std::string path;
  ExpectMentions(PendulumError("time,torque,qpos[1]\n0,1,2\n", &path),
                 {path, "unknown column 'qpos[1]'", "qpos[0]"});
}

TEST_F(CsvTest, NonNumericCellNamesLineAndColumn) {
  std::string path;
  ExpectMentions(PendulumError("time,torque,angle\n0,1,2\n0.002,abc,3\n", &path),
                 {path + ":3", "column 2", "'torque'", "'abc' is not a number"});
}

TEST_F(CsvTest, TrailingGarbageIsNotANumber) {
  std::string path;
  ExpectMentions(PendulumError("time,torque\n0,1.5x\n", &path),
                 {path + ":2", "column 2", "'1.5x'"});
}

TEST_F(CsvTest, EmptyCell) {
  // an empty time cell is an error; an empty sensor or actuator cell is a value not measured
  std::string path;
  ExpectMentions(PendulumError("time,torque,angle\n,1,3\n", &path),
                 {path + ":2", "column 1", "empty cell"});
}

TEST_F(CsvTest, NanCell) {
  std::string path;
  ExpectMentions(PendulumError("time,torque,angle\n0,1,2\nnan,1,0\n", &path),
                 {path + ":3", "column 1", "'time'", "not finite"});
  ExpectMentions(PendulumError("time,torque,angle\n0,1,2\n0.002,1,inf\n", &path),
                 {path + ":3", "column 3", "'angle'", "not finite"});
}

TEST_F(CsvTest, FieldCountMismatchNamesTheLine) {
  std::string path;
  ExpectMentions(PendulumError("time,torque,angle\n0,1,2\n0.002,1\n0.004,1,2\n", &path),
                 {path + ":3", "2 fields", "has 3"});
}

TEST_F(CsvTest, MissingActuatorColumn) {
  std::string path;
  ExpectMentions(PendulumError("time,angle\n0,1\n", &path),
                 {path, "missing actuator column 'torque'"});
}

TEST_F(CsvTest, MissingTimeColumn) {
  std::string path;
  ExpectMentions(PendulumError("torque,angle\n0,1\n", &path), {path, "missing column 'time'"});
}

TEST_F(CsvTest, DuplicateColumn) {
  std::string path;
  ExpectMentions(PendulumError("time,torque,angle,angle\n0,1,2,3\n", &path),
                 {path, "column 4", "'angle'", "duplicate", "column 3"});
}

TEST_F(CsvTest, NonIncreasingTimeNamesTheLine) {
  std::string path;
  ExpectMentions(PendulumError("time,torque\n0,1\n0.002,1\n0.002,1\n", &path),
                 {path + ":4", "'time'", "strictly increasing", "line 3"});
}

TEST_F(CsvTest, UnterminatedQuote) {
  std::string path;
  ExpectMentions(PendulumError("time,\"torque\n0,1\n", &path), {path + ":1", "unterminated"});
}

TEST_F(CsvTest, EmptyFileAndHeaderOnly) {
  std::string path;
  ExpectMentions(PendulumError("", &path), {path, "no header"});
  ExpectMentions(PendulumError("time,torque\n\n", &path), {path, "no data rows"});
}

TEST_F(CsvTest, MissingFile) {
  const std::string path = (dir_ / "nope.csv").string();
  try {
    ImportCsv(path, *pendulum_, "run");
    FAIL() << "expected LogError";
  } catch (const LogError& e) {
    ExpectMentions(e.what(), {path, "cannot open"});
  }
}

TEST_F(CsvTest, InvalidSequenceName) {
  const std::string path = Write("p.csv", "time,torque\n0,1\n");
  EXPECT_THROW(ImportCsv(path, *pendulum_, "a/b"), LogError);
  EXPECT_THROW(ImportCsv(path, *pendulum_, ""), LogError);
}

TEST_F(CsvTest, AmbiguousColumn) {
  // an actuator and a sensor may share a name in MuJoCo: such a header cannot be placed
  const ModelPtr m = LoadModelFromString(R"(<mujoco><worldbody><body>
      <joint name="j" type="hinge"/><geom size="0.1"/></body></worldbody>
      <actuator><motor name="x" joint="j"/></actuator>
      <sensor><jointpos name="x" joint="j"/></sensor></mujoco>)");
  const std::string path = Write("p.csv", "time,x\n0,1\n");
  try {
    ImportCsv(path, *m, "run");
    FAIL() << "expected LogError";
  } catch (const LogError& e) {
    ExpectMentions(e.what(), {path, "column 2", "'x'", "ambiguous"});
  }
}

}  // namespace
}  // namespace mjsysid::io
