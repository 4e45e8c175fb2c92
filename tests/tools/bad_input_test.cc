// Bad input through the real `sysid` binary (issue 7, docs/bad-input.md): truncated and corrupt
// HDF5 logs, wrong shapes, NaN rows, unknown names, malformed YAML, models that fail to compile,
// missing and empty files. Every case must
//   - exit with code 2 (not 1, not a signal),
//   - say on stderr which file (and dataset/row, YAML line:column or name) and what was expected,
//   - leave what was already written untouched: a previous fit's result folder given as --out and
//     a previous log given as --out stay byte-identical.
#include <gtest/gtest.h>
#include <hdf5.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <functional>
#include <initializer_list>
#include <limits>
#include <map>
#include <sstream>
#include <string>
#include <vector>

#include "sysid/io/log.h"
#include "tests/file_util.h"

namespace {

namespace fs = std::filesystem;
using mjsysid::test::ReadFile;
using mjsysid::test::Snapshot;
using mjsysid::test::WriteFile;
namespace io = mjsysid::io;

const std::string kModels = MJSYSID_MODELS_DIR;

struct CliRun {
  int code = -1;    // exit code; -1 when killed by a signal
  int signal = 0;   // the signal that ended it, 0 when it exited
  std::string err;  // stderr
  std::string out;  // stdout
};

class BadInputTest : public ::testing::Test {
 protected:
  // a good log, a previous fit's result folder and a previous log, shared by every case
  static void SetUpTestSuite() {
    // one folder per process: ctest runs each case as its own process, in parallel
    dir_ = mjsysid::test::FreshTempDir("bad_input");
    good_log_ = dir_ + "/good.h5";
    WriteFile(dir_ + "/good.yaml", Experiment(good_log_));
    CliRun r = Sysid("simulate " + dir_ + "/good.yaml --out " + good_log_);
    ASSERT_EQ(r.code, 0) << r.err;
    prev_ = dir_ + "/prev";
    r = Sysid("fit " + dir_ + "/good.yaml --out " + prev_ + " --quiet");
    ASSERT_EQ(r.code, 0) << r.err;
    ASSERT_TRUE(fs::exists(prev_ + "/result.yaml"));
    ASSERT_TRUE(fs::exists(prev_ + "/result.h5"));
    prev_log_ = dir_ + "/prev_log.h5";
    fs::copy_file(good_log_, prev_log_);
    prev_files_ = Snapshot(prev_);
    prev_log_bytes_ = ReadFile(prev_log_);
  }
  static void TearDownTestSuite() { fs::remove_all(dir_); }

  // the pendulum experiment on `data`, with a short simulate block
  static std::string Experiment(const std::string& data) {
    return "name: pend\n"
           "model: " +
           kModels +
           "/pendulum.xml\n"
           "data: " +
           data +
           "\n"
           "sensors:\n"
           "  - {name: angle, sigma: 0.001}\n"
           "  - {name: rate, sigma: 0.01}\n"
           "parameters:\n"
           "  - {name: damping, target: joint_damping, object: hinge, initial: 0.1,\n"
           "     bounds: [1.0e-4, 5.0], transform: log}\n"
           "solver: {max_iterations: 20, verbose: false}\n"
           "simulate:\n"
           "  truth: {damping: 0.08}\n"
           "  sequences: 1\n"
           "  steps: 200\n"
           "  noise: {angle: 0.001, rate: 0.01}\n";
  }

  // runs `sysid ARGS` (stdout and stderr kept apart)
  static CliRun Sysid(const std::string& args) {
    const std::string err_path = dir_ + "/stderr.txt";
    // a hang (HDF5 1.10 loops forever on some corrupt files) ends as SIGKILL after a minute
    const std::string cmd =
        "timeout -s KILL 60 " + std::string(MJSYSID_SYSID_BIN) + " " + args + " 2>" + err_path;
    FILE* pipe = popen(cmd.c_str(), "r");
    CliRun r;
    char buf[4096];
    while (size_t n = fread(buf, 1, sizeof(buf), pipe)) r.out.append(buf, n);
    const int status = pclose(pipe);
    if (WIFEXITED(status)) {
      r.code = WEXITSTATUS(status);
      // a shell reports a child killed by a signal as 128 + signal
      if (r.code > 128) r.signal = r.code - 128;
    } else if (WIFSIGNALED(status)) {
      r.signal = WTERMSIG(status);
    }
    r.err = ReadFile(err_path);
    return r;
  }

  // `sysid ARGS` must exit with 2, without a signal, saying each of `pieces` on stderr, and
  // leave the previous results as they were
  static CliRun ExpectBadInput(const std::string& args, std::initializer_list<std::string> pieces) {
    SCOPED_TRACE("sysid " + args);
    const CliRun r = Sysid(args);
    EXPECT_EQ(r.signal, 0) << "killed by signal " << r.signal << "\n" << r.err;
    EXPECT_EQ(r.code, 2) << r.err;
    EXPECT_NE(r.err.find("sysid "), std::string::npos) << r.err;
    for (const std::string& p : pieces) {
      EXPECT_NE(r.err.find(p), std::string::npos) << "stderr lacks '" << p << "':\n" << r.err;
    }
    // one message, no HDF5 or MuJoCo error stack dumped
    EXPECT_EQ(r.err.find("HDF5-DIAG"), std::string::npos) << r.err;
    EXPECT_LE(std::count(r.err.begin(), r.err.end(), '\n'), 3) << r.err;
    // MJSYSID_BAD_INPUT_TABLE=FILE: one line per case, for docs/bad-input.md
    if (const char* table = std::getenv("MJSYSID_BAD_INPUT_TABLE")) {
      std::string args_short = args, err = r.err;
      for (std::string* t : {&args_short, &err}) {
        for (size_t p = t->find(dir_ + "/"); p != std::string::npos; p = t->find(dir_ + "/")) {
          t->erase(p, dir_.size() + 1);
        }
        for (size_t p = t->find(kModels); p != std::string::npos; p = t->find(kModels)) {
          t->replace(p, kModels.size(), "models");
        }
      }
      while (!err.empty() && err.back() == '\n') err.pop_back();
      std::ofstream(table, std::ios::app)
          << ::testing::UnitTest::GetInstance()->current_test_info()->name() << "\t" << args_short
          << "\t" << r.code << "\t" << err << "\n";
    }
    EXPECT_EQ(Snapshot(prev_), prev_files_) << "the previous result folder changed";
    EXPECT_EQ(ReadFile(prev_log_), prev_log_bytes_) << "the previous log changed";
    return r;
  }

  // an experiment file named `name` whose data is `log`
  static std::string ExperimentOn(const std::string& name, const std::string& log) {
    const std::string path = dir_ + "/" + name;
    WriteFile(path, Experiment(log));
    return path;
  }

  // `fit` and `check` of an experiment on the log `log` must fail as bad input naming `pieces`
  static void ExpectBadLog(const std::string& log, std::initializer_list<std::string> pieces) {
    const std::string exp = ExperimentOn(fs::path(log).stem().string() + ".yaml", log);
    // each message names the log once (issue 35: nine log messages printed its path twice)
    for (const CliRun& r : {ExpectBadInput("fit " + exp + " --out " + prev_ + " --quiet", pieces),
                            ExpectBadInput("check " + exp, pieces)}) {
      size_t named = 0;
      for (size_t p = r.err.find(log); p != std::string::npos; p = r.err.find(log, p + 1)) ++named;
      EXPECT_LE(named, 1u) << r.err;
    }
  }

  // a copy of the good log, edited
  static std::string LogVariant(const std::string& name,
                                const std::function<void(io::Log*)>& edit) {
    io::Log log = io::ReadLog(good_log_);
    edit(&log);
    const std::string path = dir_ + "/" + name;
    io::WriteLog(path, log);
    return path;
  }

  // a copy of the good log with its bytes edited
  static std::string BytesVariant(const std::string& name,
                                  const std::function<void(std::string*)>& edit) {
    std::string bytes = ReadFile(good_log_);
    edit(&bytes);
    const std::string path = dir_ + "/" + name;
    WriteFile(path, bytes);
    return path;
  }

  // a copy of the good log with one element of a dataset set to `value` (HDF5 C API: WriteLog
  // refuses non-finite values)
  static std::string ElementVariant(const std::string& name, const std::string& dataset,
                                    hsize_t row, hsize_t col, double value) {
    const std::string path = dir_ + "/" + name;
    fs::copy_file(good_log_, path, fs::copy_options::overwrite_existing);
    H5Eset_auto2(H5E_DEFAULT, nullptr, nullptr);
    const hid_t f = H5Fopen(path.c_str(), H5F_ACC_RDWR, H5P_DEFAULT);
    EXPECT_GE(f, 0);
    const hid_t d = H5Dopen2(f, dataset.c_str(), H5P_DEFAULT);
    EXPECT_GE(d, 0) << dataset;
    const hid_t space = H5Dget_space(d);
    const int rank = H5Sget_simple_extent_ndims(space);
    const hsize_t start[2] = {row, col};
    const hsize_t count[2] = {1, 1};
    EXPECT_GE(H5Sselect_hyperslab(space, H5S_SELECT_SET, start, nullptr, count, nullptr), 0);
    (void)rank;
    const hsize_t one = 1;
    const hid_t mem = H5Screate_simple(1, &one, nullptr);
    EXPECT_GE(H5Dwrite(d, H5T_NATIVE_DOUBLE, mem, space, H5P_DEFAULT, &value), 0);
    H5Sclose(mem);
    H5Sclose(space);
    H5Dclose(d);
    H5Fclose(f);
    return path;
  }

  // an experiment file with the given text; `yaml` may use @LOG@, @MODELS@ and @BASE@ (three
  // good lines: the pendulum model, the good log and one parameter)
  static std::string Yaml(const std::string& name, std::string yaml) {
    const std::string base =
        "model: @MODELS@/pendulum.xml\ndata: @LOG@\n"
        "parameters: [{name: damping, target: joint_damping, object: hinge, initial: 0.1}]\n";
    for (auto [key, value] : {std::pair<std::string, std::string>{"@BASE@", base},
                              std::pair<std::string, std::string>{"@LOG@", good_log_},
                              std::pair<std::string, std::string>{"@MODELS@", kModels}}) {
      for (size_t p = yaml.find(key); p != std::string::npos; p = yaml.find(key)) {
        yaml.replace(p, key.size(), value);
      }
    }
    const std::string path = dir_ + "/" + name;
    WriteFile(path, yaml);
    return path;
  }

  // `check`, `fit` and `simulate` of an experiment must fail as bad input naming `pieces`
  static void ExpectBadExperiment(const std::string& exp, std::initializer_list<std::string> pieces,
                                  bool simulate = true) {
    ExpectBadInput("check " + exp, pieces);
    ExpectBadInput("fit " + exp + " --out " + prev_ + " --quiet", pieces);
    // --force: the experiment's error comes first, and the existing log is never touched
    if (simulate) ExpectBadInput("simulate " + exp + " --out " + prev_log_ + " --force", pieces);
  }

  static std::string dir_, good_log_, prev_, prev_log_, prev_log_bytes_;
  static std::map<std::string, std::string> prev_files_;
};

std::string BadInputTest::dir_, BadInputTest::good_log_, BadInputTest::prev_,
    BadInputTest::prev_log_, BadInputTest::prev_log_bytes_;
std::map<std::string, std::string> BadInputTest::prev_files_;

// ---------------------------------------------------------------------------------------------
// HDF5 logs

TEST_F(BadInputTest, TruncatedLog) {
  const size_t size = ReadFile(good_log_).size();
  for (size_t cut : {size_t{4}, size_t{64}, size_t{512}, size / 3, size / 2, size - 64}) {
    SCOPED_TRACE("cut at " + std::to_string(cut));
    const std::string log = BytesVariant("cut" + std::to_string(cut) + ".h5",
                                         [cut](std::string* b) { b->resize(cut); });
    ExpectBadLog(log, {log});
  }
}

TEST_F(BadInputTest, EmptyLog) {
  const std::string log = BytesVariant("empty.h5", [](std::string* b) { b->clear(); });
  ExpectBadLog(log, {log, "not an HDF5 file"});
}

TEST_F(BadInputTest, MissingLog) {
  ExpectBadLog(dir_ + "/missing.h5", {"missing.h5", "not found"});
}

TEST_F(BadInputTest, CorruptSignature) {
  const std::string log =
      BytesVariant("badsig.h5", [](std::string* b) { b->replace(0, 8, "GARBAGE!"); });
  ExpectBadLog(log, {log, "not an HDF5 file"});
}

TEST_F(BadInputTest, CorruptSuperblock) {
  // the bytes right after the signature: versions, sizes, addresses
  const std::string log = BytesVariant("badsuper.h5", [](std::string* b) {
    for (size_t i = 8; i < 48; ++i) (*b)[i] = static_cast<char>(0xA5 ^ i);
  });
  ExpectBadLog(log, {log});
}

TEST_F(BadInputTest, CorruptGlobalHeap) {
  // the collection holding the names: its first object's header zeroed (index 0, size 0), on
  // which HDF5 1.10 itself would loop forever
  const std::string log = BytesVariant("gheap.h5", [](std::string* b) {
    const size_t gcol = b->find("GCOL");
    ASSERT_NE(gcol, std::string::npos);
    for (size_t i = 16; i < 32; ++i) (*b)[gcol + i] = '\0';
  });
  ExpectBadLog(log, {log, "corrupt global heap collection"});
}

TEST_F(BadInputTest, FileThatCrashesHdf5) {
  // HDF5 1.10 itself dies of SIGSEGV on this file (found by tests/fuzz/log_fuzz): ReadLog reads
  // logs in a child process, so the crash is an error naming the file
  const std::string log = dir_ + "/segv.h5";
  fs::copy_file(MJSYSID_SOURCE_DIR "/tests/tools/data/hdf5_segv.h5", log);
  ExpectBadLog(log, {log, "the HDF5 library crashed reading the file (Segmentation fault)"});
}

TEST_F(BadInputTest, CorruptRegions) {
  // 32 bytes overwritten at pseudo-random places: where they hit metadata, exit 2; where they hit
  // sample values, the file may still be a valid log (exit 0); never a signal, a hang or exit 1
  const std::string good = ReadFile(good_log_);
  uint64_t state = 12345;
  auto next = [&state] {
    state = state * 6364136223846793005ULL + 1442695040888963407ULL;
    return state >> 33;
  };
  int bad = 0;
  for (int i = 0; i < 24; ++i) {
    const size_t at = next() % (good.size() - 32);
    SCOPED_TRACE("region at byte " + std::to_string(at));
    const std::string log = BytesVariant("region" + std::to_string(i) + ".h5", [&](std::string* b) {
      for (size_t k = 0; k < 32; ++k) (*b)[at + k] = static_cast<char>(next());
    });
    const std::string exp = ExperimentOn("region" + std::to_string(i) + ".yaml", log);
    const CliRun r = Sysid("check --no-jacobians " + exp);
    EXPECT_EQ(r.signal, 0) << r.err;
    EXPECT_TRUE(r.code == 0 || r.code == 2) << r.code << ": " << r.err;
    if (r.code == 2) {
      ++bad;
      EXPECT_NE(r.err.find(log), std::string::npos) << r.err;
    }
    EXPECT_EQ(ReadFile(prev_log_), prev_log_bytes_);
  }
  EXPECT_GT(bad, 0);
}

TEST_F(BadInputTest, TextFileAsLog) {
  const std::string log = dir_ + "/notes.h5";
  WriteFile(log, "time,torque\n0,1\n");
  ExpectBadLog(log, {log, "not an HDF5 file"});
}

TEST_F(BadInputTest, CtrlColumnsDifferFromActuators) {
  const std::string log = LogVariant("ctrl_cols.h5", [](io::Log* l) {
    io::Sequence& s = l->sequences[0];
    s.ctrl.conservativeResize(Eigen::NoChange, 2);
    s.ctrl.col(1).setZero();
    s.actuator_names.push_back("extra");
  });
  ExpectBadLog(log, {log, "/seq0/ctrl", "extra"});
}

TEST_F(BadInputTest, SensorColumnsDifferFromModel) {
  // a 3-wide "angle" where the model's is 1 wide
  const std::string log = LogVariant("sensor_cols.h5", [](io::Log* l) {
    io::Sequence& s = l->sequences[0];
    s.sensordata.conservativeResize(Eigen::NoChange, 4);
    s.sensordata.rightCols(2).setZero();
    s.sensor_dims = {3, 1};
  });
  ExpectBadLog(log, {log, "/seq0/sensordata", "angle"});
}

TEST_F(BadInputTest, TimeLengthDiffersFromRows) {
  const std::string log = dir_ + "/short_time.h5";
  fs::copy_file(good_log_, log, fs::copy_options::overwrite_existing);
  H5Eset_auto2(H5E_DEFAULT, nullptr, nullptr);
  const hid_t f = H5Fopen(log.c_str(), H5F_ACC_RDWR, H5P_DEFAULT);
  ASSERT_GE(f, 0);
  ASSERT_GE(H5Ldelete(f, "/seq0/time", H5P_DEFAULT), 0);
  std::vector<double> t(150);
  for (size_t k = 0; k < t.size(); ++k) t[k] = 0.002 * static_cast<double>(k);
  const hsize_t n = t.size();
  const hid_t space = H5Screate_simple(1, &n, nullptr);
  const hid_t d =
      H5Dcreate2(f, "/seq0/time", H5T_IEEE_F64LE, space, H5P_DEFAULT, H5P_DEFAULT, H5P_DEFAULT);
  ASSERT_GE(H5Dwrite(d, H5T_NATIVE_DOUBLE, H5S_ALL, H5S_ALL, H5P_DEFAULT, t.data()), 0);
  H5Dclose(d);
  H5Sclose(space);
  H5Fclose(f);
  ExpectBadLog(log, {log, "/seq0/", "rows", "150"});
}

TEST_F(BadInputTest, NanRows) {
  // NaN in ctrl and sensordata means "not measured" (docs/real-logs.md); in time, or Inf, an error
  const double nan = std::numeric_limits<double>::quiet_NaN();
  const double inf = std::numeric_limits<double>::infinity();
  for (const auto& [dataset, value] : std::vector<std::pair<std::string, double>>{
           {"ctrl", inf}, {"sensordata", inf}, {"time", nan}}) {
    SCOPED_TRACE(dataset);
    const std::string log =
        ElementVariant("nonfinite_" + dataset + ".h5", "/seq0/" + dataset, 17, 0, value);
    ExpectBadLog(log, {log, "/seq0/" + dataset, "row 17"});
  }
}

// Time bases (sysid/io/time_base.h), one check for import, check and fit: times that look like the
// wrong unit, non-increasing and single-sample times are bad input naming the dataset; any rate,
// gaps and NaN cells are accepted (each sample fitted at its own time)
TEST_F(BadInputTest, TimeBaseErrors) {
  // seconds written as 1/1000 of their value: the period 2 us is below 1/100 of the 2 ms timestep
  const std::string tiny =
      LogVariant("time_units.h5", [](io::Log* l) { l->sequences[0].time *= 1e-3; });
  ExpectBadLog(tiny, {tiny, "/seq0/time", "below 1/100 of the model timestep", "seconds"});
  const std::string tiny_csv = dir_ + "/time_units.csv";
  WriteFile(tiny_csv, "time,torque,angle,rate\n0,0,0,0\n0.000002,0,0,0\n0.000004,0,0,0\n");
  ExpectBadInput("import " + kModels + "/pendulum.xml " + tiny_csv + " --out " + prev_log_,
                 {"below 1/100 of the model timestep"});
  // one sample
  const std::string one_csv = dir_ + "/one_sample.csv";
  WriteFile(one_csv, "time,torque,angle,rate\n0,0,0,0\n");
  ExpectBadInput("import " + kModels + "/pendulum.xml " + one_csv + " --out " + prev_log_,
                 {"at least 2"});
  // a control NaN from the first row: nothing to hold (found when the fit is prepared)
  const std::string nan_first = LogVariant("ctrl_nan_first.h5", [](io::Log* l) {
    l->sequences[0].ctrl(0, 0) = std::numeric_limits<double>::quiet_NaN();
  });
  ExpectBadLog(nan_first, {nan_first, "/seq0/ctrl", "row 0", "'torque'", "NaN in the first row"});
  // a window (`sequences: [{name, start, end}]`) with fewer than 2 samples
  const std::string window = dir_ + "/window.yaml";
  WriteFile(window, Experiment(good_log_) + "sequences: [{name: seq0, start: 5.0, end: 6.0}]\n");
  ExpectBadInput("check " + window, {good_log_, "/seq0/time", "the window [5, 6] s holds 0"});
  // a sensor with nothing measured
  const std::string all_nan = LogVariant("sensor_all_nan.h5", [](io::Log* l) {
    l->sequences[0].sensordata.col(1).setConstant(std::numeric_limits<double>::quiet_NaN());
  });
  ExpectBadLog(all_nan, {all_nan, "/seq0/sensordata", "'rate'", "every value is NaN"});
}

// A robot's log as it comes, fitted as is: 100 Hz against the 2 ms model (every 5th step), a gap
// of 15 periods, NaN cells, float32 time. `check` and `fit` accept it (exit 0), warn about the gap
// and count the masked cells. The commands are held for 0.2 s (PRBS) and the gap lies within one
// hold: a row dropped from this one-table log drops its command too.
TEST_F(BadInputTest, OffGridGappyNanLogFitsAsIs) {
  const std::string source = dir_ + "/robot_source.h5";
  WriteFile(
      dir_ + "/robot_source.yaml",
      Experiment(source) + "  excitation: {type: prbs, amplitude: 2.0, switch_period: 0.2}\n");
  ASSERT_EQ(Sysid("simulate " + dir_ + "/robot_source.yaml --out " + source).code, 0);
  const std::string log = dir_ + "/robot.h5";
  {
    io::Log l = io::ReadLog(source);
    io::Sequence& s = l.sequences[0];
    std::vector<Eigen::Index> keep;
    for (Eigen::Index k = 0; k < s.time.size(); k += 5) {
      if (k <= 120 || k >= 195) keep.push_back(k);  // a gap of 15 periods
    }
    const auto n = static_cast<Eigen::Index>(keep.size());
    io::Sequence t = s;
    t.time.resize(n);
    t.ctrl.resize(n, s.ctrl.cols());
    t.sensordata.resize(n, s.sensordata.cols());
    for (Eigen::Index i = 0; i < n; ++i) {
      t.time[i] = s.time[keep[i]];
      t.ctrl.row(i) = s.ctrl.row(keep[i]);
      t.sensordata.row(i) = s.sensordata.row(keep[i]);
    }
    for (auto [from, to] : {std::pair{&s.qpos, &t.qpos}, {&s.qvel, &t.qvel}, {&s.act, &t.act}}) {
      to->resize(from->rows() ? n : 0, from->rows() ? from->cols() : 0);
      for (Eigen::Index i = 0; i < to->rows(); ++i) to->row(i) = from->row(keep[i]);
    }
    t.sensordata(3, 0) = t.sensordata(9, 1) = std::numeric_limits<double>::quiet_NaN();
    s = t;
    io::WriteLog(log, l);
  }
  // time stored as float32, as some loggers write it (log.h: accepted)
  {
    io::Log l = io::ReadLog(log);
    const std::vector<float> t32(l.sequences[0].time.data(),
                                 l.sequences[0].time.data() + l.sequences[0].time.size());
    H5Eset_auto2(H5E_DEFAULT, nullptr, nullptr);
    const hid_t f = H5Fopen(log.c_str(), H5F_ACC_RDWR, H5P_DEFAULT);
    ASSERT_GE(f, 0);
    ASSERT_GE(H5Ldelete(f, "/seq0/time", H5P_DEFAULT), 0);
    const hsize_t dims[1] = {t32.size()};
    const hid_t space = H5Screate_simple(1, dims, nullptr);
    const hid_t d =
        H5Dcreate2(f, "/seq0/time", H5T_IEEE_F32LE, space, H5P_DEFAULT, H5P_DEFAULT, H5P_DEFAULT);
    ASSERT_GE(d, 0);
    ASSERT_GE(H5Dwrite(d, H5T_NATIVE_FLOAT, H5S_ALL, H5S_ALL, H5P_DEFAULT, t32.data()), 0);
    H5Dclose(d);
    H5Sclose(space);
    H5Fclose(f);
  }
  const std::string exp = ExperimentOn("robot.yaml", log);
  CliRun r = Sysid("check " + exp);
  EXPECT_EQ(r.code, 0) << r.err;
  EXPECT_NE(r.err.find("gap(s) longer than 10 sample periods"), std::string::npos) << r.err;
  const std::string out = dir_ + "/robot_fit";
  r = Sysid("fit " + exp + " --out " + out + " --quiet");
  EXPECT_EQ(r.code, 0) << r.err;
  const std::string result = ReadFile(out + "/result.yaml");
  EXPECT_NE(result.find("1 of 26 values not measured (NaN)"), std::string::npos) << result;
  // a window of it, from the logged state at its first sample
  const std::string windowed = dir_ + "/robot_window.yaml";
  WriteFile(windowed, Experiment(log) + "sequences: [{name: seq0, start: 0.1, end: 0.4}]\n");
  r = Sysid("fit " + windowed + " --out " + dir_ + "/robot_window_fit --quiet");
  EXPECT_EQ(r.code, 0) << r.err;
  EXPECT_EQ(r.err.find("1 of 26"), std::string::npos) << r.err;  // the NaN of row 3 is outside
}

TEST_F(BadInputTest, LogOfAnotherModel) {
  // a log with a sensor the model does not have
  const std::string log = LogVariant("renamed.h5", [](io::Log* l) {
    l->sequences[0].sensor_names = {"angel", "rate"};
  });
  ExpectBadLog(log, {log, "angel", "did you mean 'angle'"});
}

// ---------------------------------------------------------------------------------------------
// YAML experiments

TEST_F(BadInputTest, EmptyExperiment) {
  const std::string exp = Yaml("empty.yaml", "");
  ExpectBadExperiment(exp, {exp});
}

TEST_F(BadInputTest, MissingExperiment) { ExpectBadExperiment(dir_ + "/nope.yaml", {"nope.yaml"}); }

TEST_F(BadInputTest, TabIndentation) {
  const std::string exp = Yaml("tabs.yaml", "@BASE@solver:\n\tmax_iterations: 5\n");
  ExpectBadExperiment(exp, {exp + ":5:", "YAML syntax error", "tabs"});
}

TEST_F(BadInputTest, UnclosedBracket) {
  const std::string exp =
      Yaml("bracket.yaml", "@BASE@sensors: [angle, rate\nsolver: {max_iterations: 5}\n");
  ExpectBadExperiment(exp, {exp + ":", "YAML syntax error", "brackets"});
}

TEST_F(BadInputTest, WrongTypes) {
  std::string exp = Yaml("type_int.yaml", "@BASE@solver: {max_iterations: many}\n");
  ExpectBadExperiment(exp, {exp + ":4:", "max_iterations", "many"});
  exp = Yaml("type_list.yaml",
             "model: @MODELS@/pendulum.xml\ndata: @LOG@\nparameters:\n"
             "  - {name: d, target: joint_damping, object: hinge, initial: 0.1, bounds: 3}\n");
  ExpectBadExperiment(exp, {exp + ":4:", "bounds"});
  exp = Yaml("type_map.yaml", "@BASE@solver: [1, 2]\n");
  ExpectBadExperiment(exp, {exp + ":4:", "solver"});
}

TEST_F(BadInputTest, MissingRequiredKeys) {
  std::string exp = Yaml("no_model.yaml", "data: @LOG@\nsensors: [angle]\n");
  ExpectBadExperiment(exp, {exp, "model"});
  exp = Yaml("no_target.yaml",
             "model: @MODELS@/pendulum.xml\ndata: @LOG@\nparameters:\n"
             "  - {name: d, object: hinge, initial: 0.1}\n");
  ExpectBadExperiment(exp, {exp + ":4:", "target"});
}

TEST_F(BadInputTest, DuplicateKeys) {
  std::string exp = Yaml("dup_top.yaml", "@BASE@data: other.h5\n");
  ExpectBadExperiment(exp, {exp + ":4:", "data", "duplicate"});
  exp = Yaml("dup_inner.yaml", "@BASE@solver:\n  max_iterations: 5\n  max_iterations: 6\n");
  ExpectBadExperiment(exp, {exp + ":6:", "max_iterations", "duplicate"});
}

TEST_F(BadInputTest, UnknownSensor) {
  const std::string exp = Yaml("unknown_sensor.yaml", "@BASE@sensors: [angle, rat]\n");
  ExpectBadExperiment(exp, {exp + ":4:", "rat", "did you mean 'rate'"});
}

TEST_F(BadInputTest, UnknownBodyAndJoint) {
  std::string exp = Yaml("unknown_body.yaml",
                         "model: @MODELS@/pendulum.xml\ndata: @LOG@\nparameters:\n"
                         "  - {name: m, target: body_mass, object: bobb, initial: 1.0}\n");
  ExpectBadExperiment(exp, {exp + ":4:", "bobb", "did you mean 'bob'"});
  exp = Yaml("unknown_joint.yaml",
             "model: @MODELS@/pendulum.xml\ndata: @LOG@\nparameters:\n"
             "  - {name: d, target: joint_damping, object: hnge, initial: 0.1}\n");
  ExpectBadExperiment(exp, {exp + ":4:", "hnge", "did you mean 'hinge'"});
}

TEST_F(BadInputTest, UnknownParameterName) {
  // simulate.truth names a parameter that is not declared
  const std::string exp =
      Yaml("unknown_param.yaml",
           "model: @MODELS@/pendulum.xml\ndata: @LOG@\nparameters:\n"
           "  - {name: damping, target: joint_damping, object: hinge, initial: 0.1}\n"
           "simulate:\n  truth: {dampng: 0.08}\n");
  ExpectBadExperiment(exp, {exp + ":6:", "dampng", "did you mean 'damping'"});
}

TEST_F(BadInputTest, UnknownKey) {
  const std::string exp = Yaml("unknown_key.yaml", "@BASE@solvr: {}\n");
  ExpectBadExperiment(exp, {exp + ":4:1", "solvr", "did you mean 'solver'"});
}

// ---------------------------------------------------------------------------------------------
// models

TEST_F(BadInputTest, ModelThatFailsToCompile) {
  const std::string broken = dir_ + "/broken.xml";
  WriteFile(broken, "<mujoco><worldbody><body name='b'><geom size='0.1'/></worldbody></mujoco>\n");
  const std::string attr = dir_ + "/attr.xml";
  WriteFile(attr,
            "<mujoco><worldbody><body name='b'><joint type='hinge' stifness='1'/>"
            "<geom size='0.1'/></body></worldbody></mujoco>\n");
  const std::string empty = dir_ + "/empty.xml";
  WriteFile(empty, "");
  for (const std::string& model : {broken, attr, empty}) {
    SCOPED_TRACE(model);
    const std::string exp =
        Yaml(fs::path(model).stem().string() + "_model.yaml",
             "model: " + model +
                 "\ndata: @LOG@\nparameters: [{name: s, target: joint_stiffness, "
                 "object: j, initial: 1.0}]\n");
    ExpectBadExperiment(exp, {model});
    ExpectBadInput("rollout " + model, {model});
    ExpectBadInput("import " + model + " " + dir_ + "/none.csv --out " + prev_log_, {model});
  }
  ExpectBadInput("rollout " + attr, {"stifness"});
}

TEST_F(BadInputTest, MissingModel) {
  const std::string exp =
      Yaml("missing_model.yaml", "model: " + dir_ +
                                     "/nomodel.xml\ndata: @LOG@\nparameters: [{name: s, target: "
                                     "joint_stiffness, object: j, initial: 1.0}]\n");
  ExpectBadExperiment(exp, {exp + ":1:", "nomodel.xml"});
  ExpectBadInput("rollout " + dir_ + "/nomodel.xml", {"nomodel.xml"});
}

// ---------------------------------------------------------------------------------------------
// output paths

TEST_F(BadInputTest, OutputFolderUnderAFile) {
  const std::string exp = ExperimentOn("good_copy.yaml", good_log_);
  const std::string file = dir_ + "/a_file";
  WriteFile(file, "keep me\n");
  ExpectBadInput("fit " + exp + " --out " + file + "/out --quiet",
                 {"--out", file + "/out", "cannot create the output folder"});
  ExpectBadInput("fit " + exp + " --out " + file + " --quiet", {file});
  ExpectBadInput("simulate " + exp + " --out " + file + "/log.h5", {file});
  EXPECT_EQ(ReadFile(file), "keep me\n");
}

TEST_F(BadInputTest, BadInputLeavesNoOutputBehind) {
  const std::string fresh = dir_ + "/fresh";
  const std::string exp = ExperimentOn("nan_for_fresh.yaml", dir_ + "/missing_for_fresh.h5");
  ExpectBadInput("fit " + exp + " --out " + fresh + " --quiet", {"missing_for_fresh.h5"});
  EXPECT_FALSE(fs::exists(fresh));
  ExpectBadInput("simulate " + Yaml("fresh_sim.yaml", "@BASE@sensors: [nope]\n") + " --out " +
                     fresh + "/log.h5",
                 {"nope"});
  EXPECT_FALSE(fs::exists(fresh));
}

// ---------------------------------------------------------------------------------------------
// CSV import and fit results

TEST_F(BadInputTest, CsvWithNanRowsAndUnknownColumns) {
  const std::string nan_csv = dir_ + "/nan.csv";
  WriteFile(nan_csv, "time,torque,angle,rate\n0,0,0,0\nnan,0,0,0\n");
  ExpectBadInput("import " + kModels + "/pendulum.xml " + nan_csv + " --out " + prev_log_,
                 {nan_csv, ":3:"});
  const std::string unknown_csv = dir_ + "/unknown.csv";
  WriteFile(unknown_csv, "time,torque,angel,rate\n0,0,0,0\n0.002,0,0,0\n");
  ExpectBadInput("import " + kModels + "/pendulum.xml " + unknown_csv + " --out " + prev_log_,
                 {unknown_csv, "angel"});
  const std::string empty_csv = dir_ + "/empty.csv";
  WriteFile(empty_csv, "");
  ExpectBadInput("import " + kModels + "/pendulum.xml " + empty_csv + " --out " + prev_log_,
                 {empty_csv});
  ExpectBadInput("import " + kModels + "/pendulum.xml " + dir_ + "/nocsv.csv --out " + prev_log_,
                 {"nocsv.csv"});
}

TEST_F(BadInputTest, ReportOfBrokenResults) {
  // a copy of the previous results, with each file broken in turn
  for (const char* file : {"result.yaml", "result.h5"}) {
    for (const char* how : {"empty", "truncated", "missing"}) {
      SCOPED_TRACE(std::string(file) + " " + how);
      const std::string res = dir_ + "/res_" + how;
      fs::remove_all(res);
      fs::copy(prev_, res);
      const std::string path = res + "/" + file;
      const std::string bytes = ReadFile(path);
      if (std::string(how) == "missing") {
        fs::remove(path);
      } else {
        WriteFile(path, std::string(how) == "empty" ? "" : bytes.substr(0, bytes.size() / 2));
      }
      const auto before = Snapshot(res);
      ExpectBadInput("report " + res, {path});
      EXPECT_EQ(Snapshot(res), before) << "report changed the result folder";
    }
  }
}

// ---------------------------------------------------------------------------------------------
// outputs that would lose data, limits, messages (issue 13)

TEST_F(BadInputTest, OutputIsAnInput) {
  const std::string exp = ExperimentOn("in_out.yaml", good_log_);
  const std::string exp_bytes = ReadFile(exp);
  ExpectBadInput("simulate " + exp + " --out " + exp, {"--out " + exp, "is an input of this run"});
  ExpectBadInput("simulate " + exp + " --out " + kModels + "/pendulum.xml",
                 {"pendulum.xml", "is an input of this run"});
  const std::string csv = dir_ + "/in_out.csv";
  WriteFile(csv, "time,torque,angle,rate\n0,0,0,0\n0.002,0,0,0\n");
  ExpectBadInput("import " + kModels + "/pendulum.xml " + csv + " --out " + csv,
                 {csv, "is an input of this run"});
  ExpectBadInput(
      "import " + kModels + "/pendulum.xml " + csv + " --out " + kModels + "/pendulum.xml",
      {"pendulum.xml", "is an input of this run"});
  ExpectBadInput("fit " + exp + " --out " + dir_ + " --quiet",
                 {"--out " + dir_, "holds", "an input of this run"});
  EXPECT_EQ(ReadFile(exp), exp_bytes);
  EXPECT_EQ(ReadFile(csv), "time,torque,angle,rate\n0,0,0,0\n0.002,0,0,0\n");
}

TEST_F(BadInputTest, ForeignOutputWithoutForce) {
  const std::string exp = ExperimentOn("foreign.yaml", good_log_);
  const std::string notes = dir_ + "/notes.h5";
  WriteFile(notes, "my notes\n");
  ExpectBadInput("simulate " + exp + " --out " + notes, {notes, "not an mjsysid log", "--force"});
  const std::string folder = dir_ + "/thesis";
  fs::create_directories(folder);
  WriteFile(folder + "/thesis.tex", "keep\n");
  ExpectBadInput("fit " + exp + " --out " + folder + " --quiet",
                 {folder, "not an mjsysid result folder", "--force"});
  EXPECT_EQ(ReadFile(notes), "my notes\n");
  EXPECT_EQ(ReadFile(folder + "/thesis.tex"), "keep\n");
}

TEST_F(BadInputTest, ReportOfMixedRuns) {
  const std::string other = dir_ + "/other_run";
  fs::remove_all(other);
  ASSERT_EQ(Sysid("fit " + dir_ + "/good.yaml --out " + other + " --quiet").code, 0);
  const std::string mixed = dir_ + "/mixed";
  fs::remove_all(mixed);
  fs::copy(prev_, mixed);
  fs::copy_file(other + "/result.h5", mixed + "/result.h5", fs::copy_options::overwrite_existing);
  ExpectBadInput("report " + mixed, {mixed, "the files come from different fits", "result.h5"});
  EXPECT_FALSE(fs::exists(mixed + "/report.html"));
}

TEST_F(BadInputTest, ExperimentFileTooLarge) {
  const std::string big = dir_ + "/big.yaml";
  WriteFile(big, "name: big\n" + std::string(2 << 20, '#') + "\n");
  ExpectBadExperiment(big,
                      {big, "larger than the limit of 1048576 bytes", "MJSYSID_MAX_YAML_BYTES"});
}

TEST_F(BadInputTest, NothingToFit) {
  // a log without sensor columns: zero residuals
  const std::string csv = dir_ + "/nosensors.csv";
  WriteFile(csv, "time,torque,qpos[0],qvel[0]\n0,0,0,0\n0.002,0.1,0,0\n0.004,0.1,0,0\n");
  const std::string log = dir_ + "/nosensors.h5";
  ASSERT_EQ(Sysid("import " + kModels + "/pendulum.xml " + csv + " --out " + log).code, 0);
  const std::string exp =
      Yaml("nosensors.yaml", "model: @MODELS@/pendulum.xml\ndata: " + log +
                                 "\nparameters: [{name: damping, target: "
                                 "joint_damping, object: hinge, initial: 0.1}]\n");
  ExpectBadInput("fit " + exp + " --out " + prev_ + " --quiet", {exp, "no residuals"});
  ExpectBadInput("check " + exp, {exp, "no residuals"});
}

TEST_F(BadInputTest, TwoParametersWriteOneQuantity) {
  const std::string exp = Yaml("twice.yaml",
                               "model: @MODELS@/pendulum.xml\ndata: @LOG@\nparameters:\n"
                               "  - {name: damping, target: joint_damping, object: hinge, "
                               "initial: 0.1}\n"
                               "  - {name: damping2, target: joint_damping, object: hinge, "
                               "initial: 0.2}\n");
  ExpectBadInput("fit " + exp + " --out " + prev_ + " --quiet",
                 {exp + ":5:", "'damping' and 'damping2' both write joint_damping hinge[0]"});
  ExpectBadInput("check " + exp, {"both write"});
}

TEST_F(BadInputTest, FiniteDifferenceStepThatCannotWork) {
  for (const char* step : {"1e308", "1e-300", "0.5"}) {
    const std::string exp = Yaml(std::string("step_") + step + ".yaml",
                                 "@BASE@solver: {relative_step: " + std::string(step) + "}\n");
    ExpectBadInput("fit " + exp + " --out " + prev_ + " --quiet",
                   {exp + ":4:", "relative_step", "cannot work as a finite-difference step"});
  }
}

TEST_F(BadInputTest, CsvEncodings) {
  const std::string model = kModels + "/pendulum.xml";
  const std::string header = "time,torque,angle,rate";
  const std::pair<std::string, std::string> cases[] = {
      {"utf16.csv", std::string("\xFF\xFE", 2) + "t\0i\0m\0e\0"},
      {"nul.csv", std::string("time,torque,angle,rate\n0,0\0,0,0\n", 32)},
      {"cr.csv", header + "\r0,0,0,0\r0.002,0,0,0\r"},
      {"semicolon.csv", "time;torque;angle;rate\n0;0,5;0;0\n"},
      {"decimal_comma.csv", header + "\n0,0,5,0,0\n"},
      {"huge_cell.csv", header + "\n0," + std::string(10 << 20, '7') + "x,0,0\n"}};
  const std::string expected[] = {"UTF-16",         "NUL byte at byte 26", "CR-only line ends",
                                  "';' separators", "decimal commas",      "... (10485761 bytes)"};
  for (size_t i = 0; i < std::size(cases); ++i) {
    const std::string csv = dir_ + "/" + cases[i].first;
    WriteFile(csv, cases[i].second);
    const CliRun r =
        ExpectBadInput("import " + model + " " + csv + " --out " + prev_log_, {csv, expected[i]});
    EXPECT_LT(r.err.size(), 400u) << "a long value echoed whole";
  }
}

TEST_F(BadInputTest, CommandLineMessages) {
  const std::string model = kModels + "/pendulum.xml";
  ExpectBadInput("frobnicate", {"unknown subcommand 'frobnicate'", "simulate, fit, report"});
  ExpectBadInput("rollout " + model + " --steps -1",
                 {"sysid rollout: --steps: expected a whole number >= 1, got '-1'"});
  ExpectBadInput("rollout " + model + " --amplitude nan",
                 {"--amplitude: expected a finite number, got 'nan'"});
  const CliRun r = ExpectBadInput(
      "fit " + dir_ + "/good.yaml --threads -3 --out " + prev_,
      {"--threads: expected 0 (all cores) or a whole number from 1 to 256", "got -3"});
  EXPECT_LT(r.err.size(), 200u) << r.err;
  ExpectBadInput("fit --resume " + dir_ + "/nothing_here", {"nothing to resume"});
  ExpectBadInput("report " + dir_ + "/no_such_folder", {"no_such_folder: no such folder"});
  EXPECT_FALSE(fs::exists(dir_ + "/no_such_folder.lock"));
}

// a start where the simulation fails (exit 1: the run failed) names the initial values
TEST_F(BadInputTest, FailingStartNamesTheInitialValues) {
  const std::string exp = Yaml("negative_mass.yaml",
                               "model: @MODELS@/pendulum.xml\ndata: @LOG@\nparameters:\n"
                               "  - {name: bob_mass, target: body_mass, object: bob, "
                               "initial: -1.0}\n");
  for (const std::string& cmd : {"fit " + exp + " --out " + prev_ + " --quiet", "check " + exp}) {
    SCOPED_TRACE(cmd);
    const CliRun r = Sysid(cmd);
    EXPECT_EQ(r.code, 1) << r.err;
    EXPECT_NE(r.err.find("at the initial values bob_mass = -1 (" + exp + ")"), std::string::npos)
        << r.err;
    EXPECT_EQ(Snapshot(prev_), prev_files_);
  }
}

// a simulation that diverges names the step and the time at its start: controls 0 for six
// steps, then 1 through a gain of 1e300 (bad acceleration at step 6, t = 6 x 0.002 s; MuJoCo's
// reset after a bad acceleration sets mjData::time to 0, which the message used to print)
TEST_F(BadInputTest, DivergenceNamesItsStepAndTime) {
  std::string csv = "time,torque,angle,rate\n";
  for (int k = 0; k < 20; ++k) {
    csv += std::to_string(0.002 * k) + "," + (k < 6 ? "0" : "1") + ",0,0\n";
  }
  WriteFile(dir_ + "/diverges.csv", csv);
  const std::string log = dir_ + "/diverges.h5";
  const CliRun imported =
      Sysid("import " + kModels + "/pendulum.xml " + dir_ + "/diverges.csv --out " + log);
  ASSERT_EQ(imported.code, 0) << imported.err;
  const std::string exp =
      Yaml("diverges.yaml", "model: @MODELS@/pendulum.xml\ndata: " + log +
                                "\nparameters:\n  - {name: gain, target: actuator_gain, "
                                "object: torque, initial: 1.0e300}\n");
  for (const std::string& cmd : {"fit " + exp + " --out " + prev_ + " --quiet", "check " + exp}) {
    SCOPED_TRACE(cmd);
    const CliRun r = Sysid(cmd);
    EXPECT_EQ(r.code, 1) << r.err;
    EXPECT_NE(r.err.find("simulation: sequence 0, step 6 (t = 0.012 s): MuJoCo warning: bad qacc"),
              std::string::npos)
        << r.err;
    EXPECT_EQ(Snapshot(prev_), prev_files_);
  }
}

}  // namespace
