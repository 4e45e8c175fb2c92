// Repeated warnings, report size and messages, through the real CLI (issue 35, items 4 and 7;
// docs/bad-input.md, "Issue 35: repeated warnings, report size and messages"): a warning that
// recurs for each of 2000 sequences printed once with a count and recorded once in result.yaml,
// the report's per-sequence plots capped, and the messages of a solver that never started, of
// `sysid import`'s CSV files and of `sysid report` given a file.
#include <gtest/gtest.h>
#include <hdf5.h>

#include <cstdlib>
#include <filesystem>
#include <limits>
#include <string>

#include "tests/cli_util.h"
#include "tests/file_util.h"

namespace {

namespace fs = std::filesystem;
using mjsysid::test::CliStreams;
using mjsysid::test::CountOf;
using mjsysid::test::ReadFile;
using mjsysid::test::SysidStreams;
using mjsysid::test::WriteFile;

class WarningsMessagesCliTest : public ::testing::Test {
 protected:
  static void SetUpTestSuite() { dir_ = mjsysid::test::FreshTempDir("warnings_messages_cli"); }
  static void TearDownTestSuite() {
    if (!std::getenv("NOISE36_KEEP")) fs::remove_all(dir_);
  }

  // a pendulum experiment on log `data` fitting the hinge damping, `sequences` simulated
  // sequences of `steps` steps
  static std::string Model() { return std::string(MJSYSID_SOURCE_DIR) + "/models/pendulum.xml"; }

  static std::string Experiment(const std::string& data, int sequences, int steps) {
    return "name: n36\nmodel: " + Model() + "\ndata: " + data +
           "\nsensors:\n  - {name: angle, sigma: 0.001}\n  - {name: rate, sigma: 0.01}\n"
           "parameters:\n"
           "  - {name: damping, target: joint_damping, object: hinge, initial: 0.1,\n"
           "     bounds: [1.0e-4, 5.0], transform: log}\n"
           "solver: {max_iterations: 5, verbose: false}\n"
           "simulate:\n  truth: {damping: 0.08}\n  sequences: " +
           std::to_string(sequences) + "\n  steps: " + std::to_string(steps) +
           "\n  noise: {angle: 0.001, rate: 0.01}\n";
  }

  // every sequence seq0 .. seq<n-1> of `log` without its qpos and qvel, and its sensor value at
  // row 3, column 0 NaN (not measured)
  static void StripStatesAndMaskOneValue(const std::string& log, int n) {
    const hid_t f = H5Fopen(log.c_str(), H5F_ACC_RDWR, H5P_DEFAULT);
    ASSERT_GE(f, 0);
    for (int i = 0; i < n; ++i) {
      const std::string seq = "/seq" + std::to_string(i);
      for (const char* state : {"/qpos", "/qvel"}) {
        ASSERT_GE(H5Ldelete(f, (seq + state).c_str(), H5P_DEFAULT), 0) << seq << state;
      }
      const hid_t d = H5Dopen2(f, (seq + "/sensordata").c_str(), H5P_DEFAULT);
      ASSERT_GE(d, 0);
      const hid_t space = H5Dget_space(d);
      const hsize_t start[2] = {3, 0}, count[2] = {1, 1}, one = 1;
      ASSERT_GE(H5Sselect_hyperslab(space, H5S_SELECT_SET, start, nullptr, count, nullptr), 0);
      const hid_t mem = H5Screate_simple(1, &one, nullptr);
      const double nan = std::numeric_limits<double>::quiet_NaN();
      ASSERT_GE(H5Dwrite(d, H5T_NATIVE_DOUBLE, mem, space, H5P_DEFAULT, &nan), 0);
      H5Sclose(mem);
      H5Sclose(space);
      H5Dclose(d);
    }
    H5Fclose(f);
  }

  static std::string dir_;
};

std::string WarningsMessagesCliTest::dir_;

// 2000 sequences of 20 steps, none with logged states and each with one sensor value not
// measured: every sequence gets the same two warnings ("LOG: /seqN: the log has no qpos: ..." from
// the data, "sequence 'seqN': sensor 'angle': 1 of 20 values not measured" from the fit). `check`
// and `fit --quiet` print each once, with "(and 1,999 more sequences like it: seq1, seq2, seq3,
// ...)" (exit 0); result.yaml records each once ({warning: ... {sequence} ..., count: 2000,
// sequences: [...]}), and `sysid report` reads it back (exit 0; its page lists each once). It was
// 2000 identical lines of each, on the terminal and in result.yaml.
TEST_F(WarningsMessagesCliTest, AWarningOfEverySequenceIsPrintedAndRecordedOnceWithACount) {
  const std::string log = dir_ + "/many.h5", exp = dir_ + "/many.yaml";
  WriteFile(exp, Experiment(log, 2000, 20));
  ASSERT_EQ(SysidStreams("simulate " + exp).code, 0);
  StripStatesAndMaskOneValue(log, 2000);

  const CliStreams check = SysidStreams("check " + exp);
  EXPECT_EQ(check.code, 0) << check.err;
  EXPECT_EQ(CountOf(check.err, "the log has no qpos"), 1) << check.err.substr(0, 2000);
  EXPECT_NE(check.err.find("/seq0: the log has no qpos: the fit starts from the model's reference "
                           "state (set initial_state: {estimate: true} to fit it) (and 1,999 more "
                           "sequences like it: seq1, seq2, seq3, ...)"),
            std::string::npos)
      << check.err.substr(0, 2000);

  const std::string res = dir_ + "/res_many";
  const CliStreams fit = SysidStreams("fit " + exp + " --out " + res + " --quiet");
  EXPECT_EQ(fit.code, 0) << fit.err.substr(0, 2000);
  EXPECT_EQ(CountOf(fit.err, "the log has no qpos"), 1) << fit.err.substr(0, 2000);
  EXPECT_EQ(CountOf(fit.err, "values not measured"), 1) << fit.err.substr(0, 2000);
  EXPECT_NE(fit.err.find("sequence 'seq0': sensor 'angle': 1 of 20 values not measured (NaN), "
                         "masked out of the fit (and 1,999 more sequences like it: seq1, seq2, "
                         "seq3, ...)"),
            std::string::npos)
      << fit.err.substr(0, 2000);
  EXPECT_LT(fit.err.size(), 3000u) << fit.err.substr(0, 2000);

  const std::string yaml = ReadFile(res + "/result.yaml");
  EXPECT_EQ(CountOf(yaml, "values not measured"), 1);
  EXPECT_EQ(CountOf(yaml, "the log has no qpos"), 1);
  EXPECT_NE(yaml.find("warning: \"sequence '{sequence}': sensor 'angle': 1 of 20 values not "
                      "measured (NaN), masked out of the fit\""),
            std::string::npos)
      << yaml.substr(yaml.find("warnings:"), 1500);
  EXPECT_EQ(CountOf(yaml, "count: 2000"), 2) << yaml.substr(yaml.find("warnings:"), 1500);

  // read back by the result reader (the report), the page lists each warning once
  const CliStreams report = SysidStreams("report --no-video " + res);
  EXPECT_EQ(report.code, 0) << report.err;
  const std::string page = ReadFile(res + "/report.html");
  EXPECT_EQ(CountOf(page, "values not measured"), 1);
  EXPECT_NE(page.find("(and 1,999 more sequences like it: seq1, seq2, seq3, ...)"),
            std::string::npos);
}

// A report of a fit of 40 sequences: 16 sequence plots (seq_*.png files and images on the page:
// the first 12 and the 4 others with the lowest % fit), the page saying "16 of 40 sequences
// plotted: ... 24 plots left out", and the fit quality table still naming all 40 (exit 0). It
// was one PNG per sequence, without limit (20,000 sequences, 20,000 files and images).
TEST_F(WarningsMessagesCliTest, TheReportPlotsAFewSequencesAndListsThemAll) {
  const std::string log = dir_ + "/forty.h5", exp = dir_ + "/forty.yaml", res = dir_ + "/res40";
  WriteFile(exp, Experiment(log, 40, 50));
  ASSERT_EQ(SysidStreams("simulate " + exp).code, 0);
  ASSERT_EQ(SysidStreams("fit " + exp + " --out " + res + " --quiet").code, 0);
  const CliStreams report = SysidStreams("report --no-video " + res);
  EXPECT_EQ(report.code, 0) << report.err;
  int pngs = 0;
  for (const auto& e : fs::directory_iterator(res)) {
    pngs += e.path().filename().string().rfind("seq_", 0) == 0;
  }
  EXPECT_EQ(pngs, 16);
  const std::string page = ReadFile(res + "/report.html");
  EXPECT_EQ(CountOf(page, "<img alt=\"sequence "), 16);
  EXPECT_NE(page.find("16 of 40 sequences plotted: the first 12 and the 4 others with the lowest "
                      "% fit at the estimate; 24 plots left out"),
            std::string::npos);
  for (int i = 0; i < 40; ++i) {
    EXPECT_NE(page.find("<td>seq" + std::to_string(i) + "</td>"), std::string::npos) << i;
  }
  EXPECT_TRUE(fs::exists(res + "/seq_seq11.png"));
  EXPECT_FALSE(fs::exists(res + "/seq_seq12.png") && fs::exists(res + "/seq_seq13.png") &&
               fs::exists(res + "/seq_seq14.png") && fs::exists(res + "/seq_seq15.png") &&
               fs::exists(res + "/seq_seq16.png"));
}

// A fit whose cost Ceres cannot evaluate at the start (23 rate values of 1e150 with sigma 1e-4:
// each squared residual 1e308, their sum inf): exit 4 (did_not_move), and result.yaml says what
// the summary says: `iterations: 0`, `initial_cost: .nan`, `final_cost: .nan` (the solver stopped
// before its first iteration; the termination says why); `sysid report` reads it back (exit 0)
// and says "cost        none: the solver stopped before its first iteration". It recorded -1
// iterations and costs -1 (Ceres' summary).
TEST_F(WarningsMessagesCliTest, ASolverThatNeverStartedIsRecordedWithNoIterationAndNoCost) {
  std::string csv = "time,torque,angle,rate\n";
  for (int i = 0; i < 200; ++i) {
    csv += std::to_string(0.002 * i) + ",0.1,0.3," + (i >= 17 && i < 40 ? "1e150" : "0.0") + "\n";
  }
  WriteFile(dir_ + "/edge.csv", csv);
  const std::string log = dir_ + "/edge.h5", exp = dir_ + "/edge.yaml", res = dir_ + "/res_edge";
  ASSERT_EQ(SysidStreams("import " + Model() + " " + dir_ + "/edge.csv --out " + log).code, 0);
  std::string yaml = Experiment(log, 1, 200);
  yaml.replace(yaml.find("rate, sigma: 0.01"), 17, "rate, sigma: 0.0001");
  WriteFile(exp, yaml);
  const CliStreams fit = SysidStreams("fit " + exp + " --out " + res + " --quiet");
  EXPECT_EQ(fit.code, 4) << fit.err;
  EXPECT_NE(fit.out.find("the solver stopped before its first iteration"), std::string::npos)
      << fit.out;
  const std::string result = ReadFile(res + "/result.yaml");
  EXPECT_NE(result.find("\niterations: 0\ninitial_cost: .nan\nfinal_cost: .nan\n"),
            std::string::npos)
      << result.substr(0, 800);
  EXPECT_EQ(result.find("iterations: -1"), std::string::npos);
  EXPECT_EQ(result.find("_cost: -1"), std::string::npos);
  const CliStreams report = SysidStreams("report --no-video " + res);
  EXPECT_EQ(report.code, 0) << report.err;
  EXPECT_NE(report.out.find("cost        none: the solver stopped before its first iteration"),
            std::string::npos)
      << report.out;
}

// `sysid import` of CSV files whose content is wrong: the message names the CSV file (with its
// line and column where the CSV reader sees it), never the --out log, which does not exist yet
// (exit 2, nothing written): a cell of 1e300 ("big.csv:19: column 4 ('rate'): value '1e300' is
// beyond +-1e+150, ..."), times in microseconds ("us.csv: /us/time: the median sample period
// 1e-05 s is below 1/100 of the model timestep 0.002 s: ..."); and its warnings name the CSV too
// (a gap: exit 0, "sysid import: warning: gap.csv: /gap/time: 1 gap(s) longer than 10 sample
// periods ..."). They named the --out log ("out.h5: /big/sensordata: row 17, column 1: ...").
TEST_F(WarningsMessagesCliTest, ImportMessagesNameTheCsvFileNotTheOutputLog) {
  const auto write_csv = [](const std::string& path, double period, int big_row, int gap_row) {
    std::string csv = "time,torque,angle,rate\n";
    for (int i = 0; i < 200; ++i) {
      csv += std::to_string(period * i + (gap_row >= 0 && i > gap_row ? 0.5 : 0.0)) + ",0.1,0.3," +
             (i == big_row ? "1e300" : "0.0") + "\n";
    }
    WriteFile(path, csv);
  };
  write_csv(dir_ + "/big.csv", 0.002, 17, -1);
  write_csv(dir_ + "/us.csv", 0.00001, -1, -1);
  write_csv(dir_ + "/gap.csv", 0.002, -1, 100);
  const std::string out = dir_ + "/imported.h5";
  const CliStreams big = SysidStreams("import " + Model() + " " + dir_ + "/big.csv --out " + out);
  EXPECT_EQ(big.code, 2) << big.err;
  EXPECT_NE(big.err.find("big.csv:19: column 4 ('rate'): value '1e300' is beyond +-1e+150, where "
                         "its square overflows the simulation and the cost"),
            std::string::npos)
      << big.err;
  EXPECT_EQ(big.err.find("imported.h5"), std::string::npos) << big.err;
  const CliStreams us = SysidStreams("import " + Model() + " " + dir_ + "/us.csv --out " + out);
  EXPECT_EQ(us.code, 2) << us.err;
  EXPECT_NE(us.err.find("us.csv: /us/time: the median sample period 1e-05 s is below 1/100 of "
                        "the model timestep"),
            std::string::npos)
      << us.err;
  EXPECT_EQ(us.err.find("imported.h5"), std::string::npos) << us.err;
  EXPECT_FALSE(fs::exists(out));
  const CliStreams gap = SysidStreams("import " + Model() + " " + dir_ + "/gap.csv --out " + out);
  EXPECT_EQ(gap.code, 0) << gap.err;
  EXPECT_NE(gap.err.find("sysid import: warning: " + dir_ +
                         "/gap.csv: /gap/time: 1 gap(s) longer than 10 sample periods"),
            std::string::npos)
      << gap.err;
}

// `sysid report` given a file: the fit's own result.yaml (or result.h5) stands for its folder
// (exit 0, the report written into the folder); another file is exit 2 saying what is expected
// ("FILE: is a file, not a folder: sysid report takes the output folder of `sysid fit` (the folder
// holding result.yaml and result.h5)"); a path that does not exist is exit 2 "PATH: no such folder
// (sysid report takes the output folder of `sysid fit`, ...)". A file gave "no such folder".
TEST_F(WarningsMessagesCliTest, ReportOfAResultFileReportsItsFolder) {
  const std::string log = dir_ + "/one.h5", exp = dir_ + "/one.yaml", res = dir_ + "/res_one";
  WriteFile(exp, Experiment(log, 1, 100));
  ASSERT_EQ(SysidStreams("simulate " + exp).code, 0);
  ASSERT_EQ(SysidStreams("fit " + exp + " --out " + res + " --quiet").code, 0);
  for (const std::string file : {"result.yaml", "result.h5"}) {
    fs::remove(res + "/report.html");
    const CliStreams r = SysidStreams("report --no-video " + res + "/" + file);
    EXPECT_EQ(r.code, 0) << r.err;
    EXPECT_TRUE(fs::exists(res + "/report.html")) << file;
  }
  const CliStreams other = SysidStreams("report " + exp);
  EXPECT_EQ(other.code, 2) << other.err;
  EXPECT_NE(other.err.find("one.yaml: is a file, not a folder: sysid report takes the output "
                           "folder of `sysid fit` (the folder holding result.yaml and "
                           "result.h5)"),
            std::string::npos)
      << other.err;
  const CliStreams none = SysidStreams("report " + dir_ + "/no_such_result");
  EXPECT_EQ(none.code, 2) << none.err;
  EXPECT_NE(none.err.find("no_such_result: no such folder (sysid report takes the output folder"),
            std::string::npos)
      << none.err;
}

}  // namespace
