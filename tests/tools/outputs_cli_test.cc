// Outputs that would lose data, through the real CLI (issue 35, item 1; docs/bad-input.md, "Issue
// 35: outputs that would lose data"): `simulate` replaces only a log it wrote for the same
// experiment (else exit 2 unless --force); a fit never deletes a folder holding another run's
// result, not even with --force; names that become paths are plain (no '/', not '.' or '..');
// `fit --out .` (a folder holding the current directory) is refused before any work.
#include <gtest/gtest.h>

#include <filesystem>
#include <map>
#include <string>

#include "tests/cli_util.h"
#include "tests/file_util.h"

namespace {

namespace fs = std::filesystem;
using mjsysid::test::CliStreams;
using mjsysid::test::ReadFile;
using mjsysid::test::Snapshot;
using mjsysid::test::SysidStreams;
using mjsysid::test::WriteFile;

const std::string kModels = MJSYSID_MODELS_DIR;

class Outputs35Test : public ::testing::Test {
 protected:
  void SetUp() override { dir_ = mjsysid::test::FreshTempDir("outputs_cli"); }
  void TearDown() override {
    std::error_code ec;
    fs::remove_all(dir_, ec);
  }

  // the pendulum fitting its damping from `data`, named `name` (a YAML scalar), 1 x 300 steps
  std::string Experiment(const std::string& file, const std::string& name,
                         const std::string& data) const {
    const std::string path = dir_ + "/" + file;
    WriteFile(path, "name: " + name + "\nmodel: " + kModels + "/pendulum.xml\ndata: " + data +
                        "\nsensors:\n  - {name: angle, sigma: 0.001}\n"
                        "  - {name: rate, sigma: 0.01}\n"
                        "parameters:\n"
                        "  - {name: damping, target: joint_damping, object: hinge, initial: 0.3,\n"
                        "     bounds: [1.0e-4, 5.0], transform: log}\n"
                        "solver: {max_iterations: 30, verbose: false, threads: 1}\n"
                        "simulate:\n  truth: {damping: 0.08}\n  sequences: 1\n  steps: 300\n"
                        "  noise: {angle: 0.001, rate: 0.01}\n");
    return path;
  }

  // a CSV log of the pendulum (time, torque, angle, rate), 200 rows at the model's 2 ms
  std::string Csv(const std::string& file) const {
    std::string csv = "time,torque,angle,rate\n";
    for (int k = 0; k < 200; ++k) {
      csv += std::to_string(0.002 * k) + ",0.1," + std::to_string(0.01 * k) + ",0.5\n";
    }
    WriteFile(dir_ + "/" + file, csv);
    return dir_ + "/" + file;
  }

  std::string dir_;
};

// `simulate EXP` onto its `data:` path holding a log that `sysid import` wrote from robot data:
// exit 2, "holds a log written by sysid import (...), not by sysid simulate of this experiment;
// not replaced, nothing simulated"; the file is byte for byte unchanged. With --force it is
// replaced (exit 0). It was replaced silently (exit 0).
TEST_F(Outputs35Test, SimulateDoesNotReplaceAnImportedLog) {
  const std::string log = dir_ + "/robot.h5";
  const CliStreams imported =
      SysidStreams("import " + kModels + "/pendulum.xml " + Csv("robot.csv") + " --out " + log);
  ASSERT_EQ(imported.code, 0) << imported.err;
  const std::string before = ReadFile(log);
  const std::string exp = Experiment("pend.yaml", "pend", log);
  const CliStreams r = SysidStreams("simulate " + exp);
  EXPECT_EQ(r.code, 2) << r.err;
  EXPECT_NE(r.err.find(log + " (the first `data:` path of " + exp +
                       "): holds a log written by sysid import ("),
            std::string::npos)
      << r.err;
  EXPECT_NE(r.err.find("not by sysid simulate of this experiment; not replaced, nothing "
                       "simulated (hint: --force replaces it"),
            std::string::npos)
      << r.err;
  EXPECT_EQ(ReadFile(log), before);
  const CliStreams forced = SysidStreams("simulate " + exp + " --force");
  EXPECT_EQ(forced.code, 0) << forced.err;
  EXPECT_NE(ReadFile(log), before);
}

// a log simulated by ANOTHER experiment at the same `data:` path: exit 2 naming that experiment
// ("written by sysid simulate (mjsysid V) of /abs/other.yaml"); the same experiment simulating
// again replaces its own log (exit 0)
TEST_F(Outputs35Test, SimulateReplacesOnlyItsOwnLog) {
  const std::string log = dir_ + "/shared.h5";
  const std::string other = Experiment("other.yaml", "other", log);
  const std::string mine = Experiment("mine.yaml", "mine", log);
  ASSERT_EQ(SysidStreams("simulate " + other).code, 0);
  const std::string before = ReadFile(log);
  const CliStreams r = SysidStreams("simulate " + mine);
  EXPECT_EQ(r.code, 2) << r.err;
  EXPECT_NE(r.err.find("holds a log written by sysid simulate (mjsysid "), std::string::npos)
      << r.err;
  EXPECT_NE(r.err.find(") of " + other + ", not by sysid simulate of this experiment"),
            std::string::npos)
      << r.err;
  EXPECT_EQ(ReadFile(log), before);
  const CliStreams again = SysidStreams("simulate " + other);
  EXPECT_EQ(again.code, 0) << again.err;
}

// `fit --out res` where res/cartpole/ holds another experiment's complete result: exit 2 before
// any work ("the output folder holds .../res/cartpole, a fit's result folder (it has
// result.yaml); a fit replaces the whole folder and would delete it, --force or not"), also with
// --force; the nested result is byte for byte intact. It was deleted (exit 0).
TEST_F(Outputs35Test, AFitNeverDeletesAnotherRunsResult) {
  const std::string exp = Experiment("pend.yaml", "pend", dir_ + "/log.h5");
  ASSERT_EQ(SysidStreams("simulate " + exp).code, 0);
  const std::string nested = dir_ + "/res/cartpole";
  const CliStreams first = SysidStreams("fit " + exp + " --out " + nested + " --quiet");
  ASSERT_EQ(first.code, 0) << first.err;
  const std::map<std::string, std::string> kept = Snapshot(nested);
  for (const std::string flag : {"", " --force"}) {
    SCOPED_TRACE("flag '" + flag + "'");
    const CliStreams r = SysidStreams("fit " + exp + " --out " + dir_ + "/res --quiet" + flag);
    EXPECT_EQ(r.code, 2) << r.err;
    EXPECT_NE(r.err.find("--out " + dir_ + "/res: the output folder holds " + nested +
                         ", a fit's result folder (it has result."),
              std::string::npos)
        << r.err;
    EXPECT_NE(r.err.find("would delete it, --force or not"), std::string::npos) << r.err;
    EXPECT_EQ(Snapshot(nested), kept);
    EXPECT_FALSE(fs::exists(dir_ + "/res/result.yaml"));
  }
  // a re-fit into its own previous folder replaces it (exit 0)
  const CliStreams refit = SysidStreams("fit " + exp + " --out " + nested + " --quiet");
  EXPECT_EQ(refit.code, 0) << refit.err;
  EXPECT_TRUE(fs::exists(nested + "/result.yaml"));
}

// experiment names that would become paths outside results/ or results/ itself: `.`, `..`,
// `../../x`, `a/b`: exit 2 at `check`, `simulate` and `fit`, naming the file, line and column of
// the `name:` key ("name: '.'
// is not a plain name: '.' is the folder itself"); nothing written. `../../x` wrote outside
// results/, `.` made results/ itself the output.
TEST_F(Outputs35Test, ExperimentNamesArePlainNames) {
  const std::map<std::string, std::string> cases = {{"'.'", "'.' is the folder itself"},
                                                    {"'..'", "'..' is the parent folder"},
                                                    {"'../../x'", "it contains '/'"},
                                                    {"a/b", "it contains '/'"}};
  int i = 0;
  for (const auto& [name, why] : cases) {
    SCOPED_TRACE(name);
    const std::string exp = Experiment("n" + std::to_string(i++) + ".yaml", name, "log.h5");
    for (const std::string sub : {"check ", "simulate ", "fit "}) {
      const CliStreams r = SysidStreams(sub + exp);
      EXPECT_EQ(r.code, 2) << r.err;
      EXPECT_NE(r.err.find(exp + ":1:1: name: "), std::string::npos) << r.err;
      EXPECT_NE(r.err.find(" is not a plain name: " + why), std::string::npos) << r.err;
    }
  }
  EXPECT_FALSE(fs::exists(dir_ + "/results"));
  EXPECT_FALSE(fs::exists(dir_ + "/log.h5"));
}

// a model named with '/' in a `models:` list, and an import sequence named `a/b=FILE.csv`: exit 2,
// "is not a plain name: it contains '/'", nothing written
TEST_F(Outputs35Test, ModelAndSequenceNamesArePlainNames) {
  const std::string exp = dir_ + "/models.yaml";
  WriteFile(exp, "name: m\nmodels:\n  - {name: arm/left, path: " + kModels +
                     "/pendulum.xml}\ndata: log.h5\n"
                     "parameters:\n"
                     "  - {name: damping, target: joint_damping, object: hinge, initial: 0.3}\n");
  const CliStreams r = SysidStreams("check " + exp);
  EXPECT_EQ(r.code, 2) << r.err;
  EXPECT_NE(r.err.find("'arm/left' is not a plain name: it contains '/'"), std::string::npos)
      << r.err;
  const std::string out = dir_ + "/named.h5";
  const CliStreams imp =
      SysidStreams("import " + kModels + "/pendulum.xml a/b=" + Csv("named.csv") + " --out " + out);
  EXPECT_EQ(imp.code, 2) << imp.err;
  EXPECT_NE(imp.err.find("the sequence name 'a/b' is not a plain name: it contains '/'"),
            std::string::npos)
      << imp.err;
  EXPECT_FALSE(fs::exists(out));
}

// `fit --out .` run in an empty folder of its own, and `--out` a folder that holds the current
// directory: exit 2 before any work ("--out .: the output folder is the current directory; a fit
// replaces the whole folder"), nothing written. It ran the whole fit, then failed with "Device or
// resource busy" and left `..partial/`. `--out .` in the experiment's own folder, and an output
// folder holding the experiment file, are refused as holding an input of the run (--force or not).
TEST_F(Outputs35Test, AnOutputFolderHoldingTheCurrentDirectoryOrAnInputIsRefused) {
  const std::string exp = Experiment("pend.yaml", "pend", dir_ + "/log.h5");
  ASSERT_EQ(SysidStreams("simulate " + exp).code, 0);
  fs::create_directories(dir_ + "/work/deeper");
  const std::map<std::string, std::string> before = Snapshot(dir_);
  const CliStreams dot =
      SysidStreams("fit " + exp + " --out . --quiet", 120, "cd " + dir_ + "/work; ");
  EXPECT_EQ(dot.code, 2) << dot.err;
  EXPECT_NE(dot.err.find("--out .: the output folder is the current directory; a fit replaces "
                         "the whole folder"),
            std::string::npos)
      << dot.err;
  const CliStreams up = SysidStreams("fit " + exp + " --out " + dir_ + "/work --quiet", 120,
                                     "cd " + dir_ + "/work/deeper; ");
  EXPECT_EQ(up.code, 2) << up.err;
  EXPECT_NE(up.err.find("the output folder holds the current directory"), std::string::npos)
      << up.err;
  for (const std::string flag : {"", " --force"}) {
    const CliStreams own =
        SysidStreams("fit " + exp + " --out . --quiet" + flag, 120, "cd " + dir_ + "; ");
    EXPECT_EQ(own.code, 2) << own.err;
    EXPECT_NE(own.err.find("--out .: the output folder holds " + exp + ", an input of this run"),
              std::string::npos)
        << own.err;
  }
  EXPECT_EQ(Snapshot(dir_), before);  // nothing written: no ..partial, no result
}

}  // namespace
