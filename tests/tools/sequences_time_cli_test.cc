// Sequences identified by file and group, and logged times in the wrong unit, through the real CLI
// (issue 35, items 2 and 5; docs/bad-input.md, "Issue 35: sequence names and time units").
// Item 2: logs of `sysid simulate` all name their groups seq0, seq1, ...; a group name found
// in several logs is named "<log file stem>:<group>" in the fit, its result files and report
// (the rule: io::SequenceNamesInFit, sysid/io/sequence_models.h); a name that still collides, and
// a log listed twice, are refused before anything is simulated. Item 5: a median sample period
// above 100 x the model timestep, or a log longer than a day, is refused at import, check and fit
// with the likely unit; `sysid import --time-scale FACTOR` converts.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <string>
#include <vector>

#include "sysid/io/log.h"
#include "sysid/io/result.h"
#include "tests/cli_util.h"
#include "tests/file_util.h"

namespace {

namespace fs = std::filesystem;
namespace io = mjsysid::io;
using mjsysid::test::CliStreams;
using mjsysid::test::CountOf;
using mjsysid::test::FitKilledAtCheckpoint;
using mjsysid::test::SysidStreams;
using mjsysid::test::WriteFile;

const std::string kModels = MJSYSID_MODELS_DIR;

// names of a result's sequences (fitted, then held out)
std::vector<std::string> Names(const std::vector<mjsysid::SequenceResult>& list) {
  std::vector<std::string> names;
  for (const mjsysid::SequenceResult& s : list) names.push_back(s.name);
  return names;
}

class SequencesTime35Test : public ::testing::Test {
 protected:
  void SetUp() override { dir_ = mjsysid::test::FreshTempDir("sequences_time_cli"); }
  void TearDown() override {
    std::error_code ec;
    fs::remove_all(dir_, ec);
  }

  // a pendulum experiment fitting the damping from `data` (a YAML scalar or flow list); its
  // `simulate:` writes `sequences` sequences of `steps` steps with `seed`; `extra`: more lines
  static std::string Experiment(const std::string& data, int sequences = 1, int steps = 300,
                                int seed = 1, const std::string& extra = "") {
    return "name: st35\nmodel: " + kModels + "/pendulum.xml\ndata: " + data +
           "\nsensors:\n  - {name: angle, sigma: 0.001}\n  - {name: rate, sigma: 0.01}\n"
           "parameters:\n"
           "  - {name: damping, target: joint_damping, object: hinge, initial: 0.3,\n"
           "     bounds: [1.0e-4, 5.0], transform: log}\n"
           "solver: {max_iterations: 50, verbose: false, threads: 1}\n" +
           extra +
           "simulate:\n  truth: {damping: 0.08}\n  sequences: " + std::to_string(sequences) +
           "\n  steps: " + std::to_string(steps) + "\n  seed: " + std::to_string(seed) +
           "\n  noise: {angle: 0.001, rate: 0.01}\n  initial_state: {qpos: [0.3], qvel: [0.0]}\n";
  }

  // `sysid simulate` of the pendulum into dir_/<log> (relative to dir_)
  void SimulateLog(const std::string& log, int sequences, int seed, int steps = 300) {
    const std::string exp = dir_ + "/sim_" + std::to_string(seed) + ".yaml";
    fs::create_directories(fs::path(dir_ + "/" + log).parent_path());
    WriteFile(exp, Experiment(log, sequences, steps, seed));
    const CliStreams r = SysidStreams("simulate " + exp);
    ASSERT_EQ(r.code, 0) << r.err;
  }

  // dir_/<name>.yaml with Experiment(data, ..., extra)
  std::string WriteExperiment(const std::string& name, const std::string& data,
                              const std::string& extra = "") {
    const std::string path = dir_ + "/" + name + ".yaml";
    WriteFile(path, Experiment(data, 1, 300, 1, extra));
    return path;
  }

  // dir_/runA.h5 (seq0, seq1) and dir_/runB.h5 (seq0), both written by `sysid simulate`
  void TwoSimulatedLogs(int steps = 300) {
    SimulateLog("runA.h5", 2, 1, steps);
    SimulateLog("runB.h5", 1, 2, steps);
  }

  // the pendulum log dir_/<name>.h5 (one sequence "seq0" of 300 samples at the model's 0.002 s)
  // with its times replaced by `time(k)` of sample k
  template <typename F>
  std::string LogWithTimes(const std::string& name, F time) {
    const std::string path = dir_ + "/" + name + ".h5";
    SimulateLog(name + ".h5", 1, 7);
    io::Log log = io::ReadLog(path);
    Eigen::VectorXd& t = log.sequences[0].time;
    for (Eigen::Index k = 0; k < t.size(); ++k) t[k] = time(k);
    io::WriteLog(path, log);  // the model is not known here: no time-base check
    return path;
  }

  std::string dir_;
};

// --- item 2: sequences identified by file and group -------------------------------------------

// Two logs of `sysid simulate` (runA: seq0, seq1; runB: seq0) in one fit: exit 0 (it was exit 1
// after the whole fit: "two sequences are named 'seq0'" writing result.h5). The colliding groups
// are runA:seq0 and runB:seq0 (seq1 keeps its name) in the summary, result.yaml, result.h5 (read
// back) and the report, whose motion clip finds runA:seq0 again; one warning says so.
TEST_F(SequencesTime35Test, GroupsOfOneNameInTwoLogsAreNamedAfterTheirFiles) {
  TwoSimulatedLogs();
  const std::string exp = WriteExperiment("ab", "[runA.h5, runB.h5]");
  const CliStreams fit = SysidStreams("fit " + exp + " --out " + dir_ + "/res --quiet");
  ASSERT_EQ(fit.code, 0) << fit.err;
  EXPECT_EQ(
      CountOf(fit.err, "sysid fit: warning: sequence 'seq0' is in 2 logs (" + dir_ + "/runA.h5, " +
                           dir_ + "/runB.h5): named runA:seq0, runB:seq0 in the fit"),
      1)
      << fit.err;
  EXPECT_NE(fit.out.find("  runA:seq0 "), std::string::npos) << fit.out;
  EXPECT_NE(fit.out.find("  runB:seq0 "), std::string::npos) << fit.out;
  const io::FitResultFile result = io::ReadResult(dir_ + "/res");
  EXPECT_EQ(Names(result.sequences), (std::vector<std::string>{"runA:seq0", "seq1", "runB:seq0"}));
  const std::string yaml = mjsysid::test::ReadFile(dir_ + "/res/result.yaml");
  EXPECT_NE(yaml.find("sequence: runA:seq0\n"), std::string::npos) << yaml;
  const CliStreams report = SysidStreams("report " + dir_ + "/res");
  ASSERT_EQ(report.code, 0) << report.err;
  EXPECT_NE(report.out.find("motion      runA:seq0:"), std::string::npos) << report.out;
  EXPECT_TRUE(fs::exists(dir_ + "/res/seq_runA_seq0.png"));
  EXPECT_TRUE(fs::exists(dir_ + "/res/seq_runB_seq0.png"));
}

// `check` of the same experiment: exit 0, the same warning as `fit` and the fitted sequences under
// the same names.
TEST_F(SequencesTime35Test, CheckReportsTheNamesAsFitDoes) {
  TwoSimulatedLogs();
  const std::string exp = WriteExperiment("ab", "[runA.h5, runB.h5]");
  const CliStreams r = SysidStreams("check " + exp);
  ASSERT_EQ(r.code, 0) << r.err;
  EXPECT_EQ(
      CountOf(r.err, "sysid check: warning: sequence 'seq0' is in 2 logs (" + dir_ + "/runA.h5, " +
                         dir_ + "/runB.h5): named runA:seq0, runB:seq0 in the fit"),
      1)
      << r.err;
  EXPECT_NE(r.out.find("  fitted     runA:seq0, seq1, runB:seq0\n"), std::string::npos) << r.out;
}

// Held out (`validation: [seq0]`: seq0 of both logs): exit 0; /validation of result.h5 holds
// runA:seq0 and runB:seq0, the fitted seq1 keeps its name (it was exit 1 at the end).
TEST_F(SequencesTime35Test, HeldOutSequencesAreNamedByTheSameRule) {
  TwoSimulatedLogs();
  const std::string exp = WriteExperiment("ab", "[runA.h5, runB.h5]", "validation: [seq0]\n");
  const CliStreams fit = SysidStreams("fit " + exp + " --out " + dir_ + "/res --quiet");
  ASSERT_EQ(fit.code, 0) << fit.err;
  const io::FitResultFile result = io::ReadResult(dir_ + "/res");
  EXPECT_EQ(Names(result.sequences), std::vector<std::string>{"seq1"});
  EXPECT_EQ(Names(result.validation), (std::vector<std::string>{"runA:seq0", "runB:seq0"}));
}

// Two models (cart, cart_payload), two logs of one `sysid simulate` experiment (groups cart_seq0,
// cart_seq1, cart_payload_seq0, cart_payload_seq1 in both, each recorded for its model by the log's
// attribute sequences.<model>): exit 0; every sequence is named after its file and keeps the model
// its own log records.
TEST_F(SequencesTime35Test, SeveralModelsKeepTheirSequencesWhenRenamed) {
  auto experiment = [&](const std::string& data, int seed) {
    return "name: pair\nmodels:\n  - {name: cart, path: " + kModels +
           "/cart.xml}\n  - {name: cart_payload, path: " + kModels +
           "/cart_payload.xml}\ndata: " + data +
           "\nsensors: [x, xdot]\nparameters:\n"
           "  - {name: mass, target: body_mass, object: cart, initial: 1.2, bounds: [0.1, 10],\n"
           "     transform: log}\n"
           "solver: {max_iterations: 30, verbose: false, threads: 1}\n"
           "simulate:\n  truth: {mass: 2.0}\n  sequences: 2\n  steps: 200\n  seed: " +
           std::to_string(seed) + "\n";
  };
  for (const auto& [log, seed] : {std::pair<std::string, int>{"left.h5", 1}, {"right.h5", 2}}) {
    WriteFile(dir_ + "/sim.yaml", experiment(log, seed));
    ASSERT_EQ(SysidStreams("simulate " + dir_ + "/sim.yaml").code, 0);
  }
  WriteFile(dir_ + "/pair.yaml", experiment("[left.h5, right.h5]", 1));
  const CliStreams fit = SysidStreams("fit " + dir_ + "/pair.yaml --out " + dir_ + "/res --quiet");
  ASSERT_EQ(fit.code, 0) << fit.err;
  const io::FitResultFile result = io::ReadResult(dir_ + "/res");
  ASSERT_EQ(result.sequences.size(), 8u);  // 2 per model in each log
  for (const mjsysid::SequenceResult& s : result.sequences) {
    const size_t colon = s.name.find(':');
    ASSERT_NE(colon, std::string::npos) << s.name;
    const std::string file = s.name.substr(0, colon), group = s.name.substr(colon + 1);
    EXPECT_TRUE(file == "left" || file == "right") << s.name;
    // simulate names a model's groups <model>_seq<i>: the model recorded for the group
    EXPECT_EQ(group.rfind(s.model + "_seq", 0), 0u) << s.name << " fitted with " << s.model;
    EXPECT_EQ(group.find("payload") != std::string::npos, s.model == "cart_payload") << s.name;
  }
}

// `sequences:` and `validation:` entries may name a group in one log by its name in the fit:
// `sequences: [runA:seq0, seq1]`, `validation: [runB:seq0]` checks (exit 0) with runA:seq0 and
// seq1 fitted and runB:seq0 held out; `sequences: [runA:seq0]` with `validation: [seq0]` names
// runA's seq0 in both lists: exit 2, "runA.h5: /seq0: is named by `sequences:` and by
// `validation:`: a validation sequence is held out of the fit (remove it from one of the lists)".
TEST_F(SequencesTime35Test, EntriesNameAGroupOfOneLogByItsNameInTheFit) {
  TwoSimulatedLogs();
  const std::string ok = WriteExperiment("q1", "[runA.h5, runB.h5]",
                                         "sequences: [runA:seq0, seq1]\nvalidation: [runB:seq0]\n");
  const CliStreams r = SysidStreams("check " + ok);
  ASSERT_EQ(r.code, 0) << r.err;
  EXPECT_NE(r.out.find("  fitted     runA:seq0, seq1\n"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("  validation runB:seq0 (held out"), std::string::npos) << r.out;
  const std::string both =
      WriteExperiment("q2", "[runA.h5, runB.h5]", "sequences: [runA:seq0]\nvalidation: [seq0]\n");
  const CliStreams bad = SysidStreams("check " + both);
  EXPECT_EQ(bad.code, 2) << bad.err;
  EXPECT_NE(bad.err.find(dir_ + "/runA.h5: /seq0: is named by `sequences:` and by `validation:`"),
            std::string::npos)
      << bad.err;
}

// A fit of runA and runB killed at its first checkpoint, then `fit --resume`: exit 0, the result
// names runA:seq0 and runB:seq0 (the resume used to fail writing it like the fit).
TEST_F(SequencesTime35Test, AResumedFitWritesTheRenamedSequences) {
  TwoSimulatedLogs(3000);
  const std::string exp = WriteExperiment("ab", "[runA.h5, runB.h5]");
  const std::string out = dir_ + "/res";
  ASSERT_TRUE(FitKilledAtCheckpoint(exp, out)) << "the fit ended before the kill";
  const CliStreams r = SysidStreams("fit --resume " + out + " --quiet");
  ASSERT_EQ(r.code, 0) << r.err;
  const io::FitResultFile result = io::ReadResult(out);
  EXPECT_EQ(Names(result.sequences), (std::vector<std::string>{"runA:seq0", "seq1", "runB:seq0"}));
}

// One log listed twice in `data:` (the same path, then through a symlink): exit 2 naming the file
// and the YAML line of the second entry, "data file listed twice: ... (hint: first given at line
// 3, column 8; its data would count twice: list each log once)"; no output folder (it used to
// count the data twice, or fail at the end).
TEST_F(SequencesTime35Test, ALogListedTwiceIsRefused) {
  SimulateLog("runA.h5", 1, 1);
  fs::create_symlink(dir_ + "/runA.h5", dir_ + "/alias.h5");
  for (const std::string second : {"./runA.h5", "alias.h5"}) {
    SCOPED_TRACE(second);
    const std::string exp = WriteExperiment("twice", "[runA.h5, " + second + "]");
    for (const std::string& cmd : {"check " + exp, "fit " + exp + " --out " + dir_ + "/res"}) {
      const CliStreams r = SysidStreams(cmd);
      EXPECT_EQ(r.code, 2) << r.err;
      EXPECT_NE(r.err.find(exp + ":3:"), std::string::npos) << r.err;
      EXPECT_NE(r.err.find(": data file listed twice: " + dir_ + "/"), std::string::npos) << r.err;
      EXPECT_NE(r.err.find("first given at line 3, column 8"), std::string::npos) << r.err;
      EXPECT_EQ(CountOf(r.err, "\n"), 1) << r.err;
      EXPECT_FALSE(fs::exists(dir_ + "/res"));
    }
  }
}

// Two logs with the same file name in two folders (x/run.h5, y/run.h5, both with seq0): the
// renamed names collide too: exit 2 naming both files, "x/run.h5: /seq0 and y/run.h5: /seq0
// would both be named 'run:seq0' in the fit (...): rename one of the log files or groups", at
// `check` and at `fit` before anything is simulated (no output folder).
TEST_F(SequencesTime35Test, NamesThatStillCollideAreRefused) {
  SimulateLog("x/run.h5", 1, 1);
  SimulateLog("y/run.h5", 1, 2);
  const std::string exp = WriteExperiment("xy", "[x/run.h5, y/run.h5]");
  for (const std::string& cmd : {"check " + exp, "fit " + exp + " --out " + dir_ + "/res"}) {
    const CliStreams r = SysidStreams(cmd);
    EXPECT_EQ(r.code, 2) << r.err;
    EXPECT_NE(r.err.find(dir_ + "/x/run.h5: /seq0 and " + dir_ +
                         "/y/run.h5: /seq0 would both be named 'run:seq0' in the fit"),
              std::string::npos)
        << r.err;
    EXPECT_EQ(r.out.find("simulating"), std::string::npos) << r.out;
    EXPECT_FALSE(fs::exists(dir_ + "/res"));
  }
}

// --- item 5: time units ------------------------------------------------------------------------

// A CSV log whose time is in milliseconds (2, 4, 6, ... on the 0.002 s pendulum): `import` exits
// 2, "the median sample period 2 s is more than 100 x the model timestep 0.002 s: time looks like
// milliseconds: periods of 2 'seconds' on a 0.002 s model; time must be in seconds: ... `sysid
// import --time-scale 0.001`", and writes nothing; with --time-scale 0.001 exit 0 and the log's
// times are in seconds (0.002 apart).
TEST_F(SequencesTime35Test, MillisecondsAreRefusedAtImportAndConvertedWithTimeScale) {
  std::string csv = "time,torque,angle,rate\n";
  for (int k = 0; k < 300; ++k) {
    csv += std::to_string(2 * k) + "," + std::to_string(0.1 * std::sin(0.01 * k)) + "," +
           std::to_string(0.3 * std::cos(0.004 * k)) + ",0.1\n";
  }
  WriteFile(dir_ + "/ms.csv", csv);
  const std::string model = kModels + "/pendulum.xml";
  const CliStreams bad =
      SysidStreams("import " + model + " " + dir_ + "/ms.csv --out " + dir_ + "/ms.h5");
  EXPECT_EQ(bad.code, 2) << bad.err;
  EXPECT_NE(bad.err.find("/ms.csv: /ms/time: the median sample period 2 s is more than 100 x the "
                         "model timestep 0.002 s: time looks like milliseconds: periods of 2 "
                         "'seconds' on a 0.002 s model; time must be in seconds"),
            std::string::npos)
      << bad.err;
  EXPECT_NE(bad.err.find("`sysid import --time-scale 0.001`"), std::string::npos) << bad.err;
  EXPECT_FALSE(fs::exists(dir_ + "/ms.h5"));
  const CliStreams good = SysidStreams("import " + model + " " + dir_ + "/ms.csv --out " + dir_ +
                                       "/ms.h5 --time-scale 0.001");
  ASSERT_EQ(good.code, 0) << good.err;
  const io::Log log = io::ReadLog(dir_ + "/ms.h5");
  EXPECT_DOUBLE_EQ(log.sequences[0].time[299], 0.598);
}

// --time-scale that is not a finite number > 0 (0, -1, nan, inf, 1e400, abc): exit 2,
// "--time-scale: expected a finite number > 0 (...), got '0'"; nothing written.
TEST_F(SequencesTime35Test, ABadTimeScaleIsRefused) {
  WriteFile(dir_ + "/s.csv", "time,torque,angle,rate\n0,0,0,0\n0.002,0,0,0\n0.004,0,0,0\n");
  for (const std::string factor : {"0", "-1", "nan", "inf", "1e400", "abc"}) {
    SCOPED_TRACE(factor);
    const CliStreams r = SysidStreams("import " + kModels + "/pendulum.xml " + dir_ +
                                      "/s.csv --out " + dir_ + "/s.h5 --time-scale=" + factor);
    EXPECT_EQ(r.code, 2) << r.err;
    EXPECT_NE(r.err.find("sysid import: --time-scale: expected a finite number > 0"),
              std::string::npos)
        << r.err;
    EXPECT_NE(r.err.find("got '" + factor + "'"), std::string::npos) << r.err;
    EXPECT_FALSE(fs::exists(dir_ + "/s.h5"));
  }
}

// An HDF5 log whose time is in nanoseconds (2e6 apart on the 0.002 s pendulum): `check` and `fit`
// exit 2, "/seq0/time: the median sample period 2e+06 s is more than 100 x the model timestep
// 0.002 s: time looks like nanoseconds: ... `sysid import --time-scale 1e-9`", before anything is
// simulated (it used to simulate 1e9 x the steps or die with std::bad_alloc); no output folder.
TEST_F(SequencesTime35Test, NanosecondsAreRefusedAtCheckAndFit) {
  LogWithTimes("ns", [](Eigen::Index k) { return 2e6 * static_cast<double>(k); });
  const std::string exp = WriteExperiment("ns", "ns.h5");
  for (const std::string& cmd : {"check " + exp, "fit " + exp + " --out " + dir_ + "/res"}) {
    const CliStreams r = SysidStreams(cmd, 60);
    EXPECT_EQ(r.code, 2) << r.err;
    EXPECT_NE(r.err.find(dir_ + "/ns.h5: /seq0/time: the median sample period 2e+06 s is more "
                                "than 100 x the model timestep 0.002 s: time looks like "
                                "nanoseconds"),
              std::string::npos)
        << r.err;
    EXPECT_NE(r.err.find("--time-scale 1e-9`"), std::string::npos) << r.err;
    EXPECT_EQ(CountOf(r.err, "\n"), 1) << r.err;
    EXPECT_FALSE(fs::exists(dir_ + "/res"));
  }
}

// A log at the model's rate that spans more than a day (299 samples 0.002 s apart, the last one
// at 90000 s): `check` exits 2, "the log spans 90000 s (0 .. 90000), more than one day (86400 s):
// time must be in seconds: ... `sysid import --time-scale FACTOR` (0.001 for milliseconds, ...)".
TEST_F(SequencesTime35Test, ALogLongerThanADayIsRefused) {
  LogWithTimes("day", [](Eigen::Index k) { return k == 299 ? 90000.0 : 0.002 * k; });
  const std::string exp = WriteExperiment("day", "day.h5");
  const CliStreams r = SysidStreams("check " + exp);
  EXPECT_EQ(r.code, 2) << r.err;
  EXPECT_NE(r.err.find("/day.h5: /seq0/time: the log spans 90000 s (0 .. 90000), more than one "
                       "day (86400 s): time must be in seconds"),
            std::string::npos)
      << r.err;
  // no smaller unit is likely (the period is the model's): no factor is suggested
  EXPECT_NE(r.err.find("`sysid import --time-scale FACTOR` (0.001 for milliseconds, 1e-9 for "
                       "nanoseconds)"),
            std::string::npos)
      << r.err;
}

// The bound is on a sequence's sample times: a sensor at its own slow rate (angle at 1 Hz in its
// own CSV file, rate and the controls at 500 Hz) imports (exit 0) and checks (exit 0); the same
// sequence with every sensor at 1 Hz is refused at import (exit 2: its sample times, the union of
// the sensors' times, are 1 s = 500 x 0.002 s apart).
TEST_F(SequencesTime35Test, ASlowSensorAtItsOwnTimesIsAccepted) {
  std::string fast = "time,torque,rate\n", slow = "time,angle\n", slow_rate = "time,rate\n";
  for (int k = 0; k < 2000; ++k) {
    fast += std::to_string(0.002 * k) + "," + std::to_string(0.1 * std::sin(0.01 * k)) + ",0.1\n";
  }
  for (int k = 0; k < 4; ++k) {
    slow += std::to_string(k) + ",0.3\n";
    slow_rate += std::to_string(k) + ",0.1\n";
  }
  WriteFile(dir_ + "/fast.csv", fast);
  WriteFile(dir_ + "/slow.csv", slow);
  WriteFile(dir_ + "/slow_rate.csv", slow_rate);
  WriteFile(dir_ + "/ctrl.csv", "time,torque\n0,0\n0.002,0\n4,0\n");
  const std::string model = kModels + "/pendulum.xml";
  const CliStreams ok = SysidStreams("import " + model + " run=" + dir_ + "/fast.csv+" + dir_ +
                                     "/slow.csv --out " + dir_ + "/own.h5");
  ASSERT_EQ(ok.code, 0) << ok.err;
  const std::string exp = WriteExperiment("own", "own.h5");
  const CliStreams check = SysidStreams("check " + exp);
  EXPECT_EQ(check.code, 0) << check.err;
  const CliStreams bad =
      SysidStreams("import " + model + " run=" + dir_ + "/ctrl.csv+" + dir_ + "/slow.csv+" + dir_ +
                   "/slow_rate.csv --out " + dir_ + "/slow.h5");
  EXPECT_EQ(bad.code, 2) << bad.err;
  EXPECT_NE(
      bad.err.find("/slow_rate.csv: /run/time: the median sample period 1 s is more than 100 x "
                   "the model timestep 0.002 s: "),
      std::string::npos)
      << bad.err;
}

}  // namespace
