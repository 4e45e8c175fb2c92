// the `sysid` command line as a user runs it: subcommands, outputs and exit codes
#include <gtest/gtest.h>
#include <sys/wait.h>

#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <string>

#include "tests/cli_util.h"
#include "tests/file_util.h"

namespace {

namespace fs = std::filesystem;

using mjsysid::test::CliRun;
using mjsysid::test::Sysid;

std::string TempDir(const std::string& name) { return mjsysid::test::FreshTempDir("cli_" + name); }

const std::string kExperiments = MJSYSID_EXPERIMENTS_DIR;
const std::string kModels = MJSYSID_MODELS_DIR;

TEST(SysidCliTest, HelpListsEverySubcommand) {
  const CliRun r = Sysid("--help");
  EXPECT_EQ(r.code, 0);
  for (const char* sub : {"simulate", "fit", "report", "check", "import", "rollout", "design"}) {
    EXPECT_NE(r.output.find(sub), std::string::npos) << sub;
  }
  EXPECT_EQ(Sysid("fit --help").code, 0);
  EXPECT_EQ(Sysid("frobnicate").code, 2);
  EXPECT_EQ(Sysid("").code, 2);
}

// simulate -> check -> fit -> report on the spring-mass experiment
TEST(SysidCliTest, SimulateFitReportEndToEnd) {
  const std::string dir = TempDir("e2e");
  const std::string exp = kExperiments + "/spring_mass.yaml";
  ASSERT_EQ(Sysid("simulate " + exp + " --out " + dir + "/log.h5").code, 0);
  // point a copy of the experiment at that log
  std::ifstream in(exp);
  std::string yaml((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  const size_t at = yaml.find("data:");
  ASSERT_NE(at, std::string::npos);
  yaml.replace(at, yaml.find('\n', at) - at, "data: " + dir + "/log.h5");
  for (size_t p = yaml.find("../models/"); p != std::string::npos; p = yaml.find("../models/")) {
    yaml.replace(p, 10, kModels + "/");
  }
  std::ofstream(dir + "/exp.yaml") << yaml;
  const CliRun check = Sysid("check " + dir + "/exp.yaml");
  EXPECT_EQ(check.code, 0) << check.output;
  EXPECT_NE(check.output.find("OK"), std::string::npos);
  const CliRun fit = Sysid("fit " + dir + "/exp.yaml --out " + dir + "/out --quiet");
  EXPECT_EQ(fit.code, 0) << fit.output;
  EXPECT_NE(fit.output.find("converged"), std::string::npos) << fit.output;
  for (const char* f : {"result.yaml", "result.h5", "spring_mass_identified.xml"}) {
    EXPECT_TRUE(fs::exists(dir + "/out/" + f)) << f;
  }
  const CliRun report = Sysid("report " + dir + "/out");
  EXPECT_EQ(report.code, 0) << report.output;
  EXPECT_TRUE(fs::exists(dir + "/out/report.html"));
  fs::remove_all(dir);
}

// bad input: exit code 2 and a message naming the problem
TEST(SysidCliTest, BadInputExitsWithTwoAndNamesTheProblem) {
  const std::string dir = TempDir("bad");
  CliRun r = Sysid("fit " + dir + "/missing.yaml");
  EXPECT_EQ(r.code, 2);
  EXPECT_NE(r.output.find("missing.yaml"), std::string::npos) << r.output;

  std::ofstream(dir + "/typo.yaml") << "model: " << kModels << "/pendulum.xml\nparamters: []\n";
  r = Sysid("check " + dir + "/typo.yaml");
  EXPECT_EQ(r.code, 2);
  EXPECT_NE(r.output.find("typo.yaml:2:1"), std::string::npos) << r.output;

  r = Sysid("rollout " + dir + "/nope.xml");
  EXPECT_EQ(r.code, 2);
  r = Sysid("report " + dir);
  EXPECT_EQ(r.code, 2) << r.output;
  fs::remove_all(dir);
}

TEST(SysidCliTest, ImportCsvIntoAValidatedLog) {
  const std::string dir = TempDir("import");
  {
    std::ofstream csv(dir + "/run1.csv");
    csv << "time,torque,angle,rate\n";
    for (int k = 0; k < 50; ++k) csv << k * 0.002 << ",0.5,0.1,0.0\n";
  }
  CliRun r =
      Sysid("import " + kModels + "/pendulum.xml " + dir + "/run1.csv --out " + dir + "/log.h5");
  EXPECT_EQ(r.code, 0) << r.output;
  EXPECT_TRUE(fs::exists(dir + "/log.h5"));
  std::ofstream(dir + "/bad.csv") << "time,torq,angle\n0,1,2\n";
  r = Sysid("import " + kModels + "/pendulum.xml " + dir + "/bad.csv --out " + dir + "/x.h5");
  EXPECT_EQ(r.code, 2);
  EXPECT_NE(r.output.find("did you mean 'torque'"), std::string::npos) << r.output;
  EXPECT_FALSE(fs::exists(dir + "/x.h5"));
  fs::remove_all(dir);
}

// a copy of a shipped experiment in dir, its models absolute, its data `log`, plus `extra` lines
std::string ExperimentCopy(const std::string& name, const std::string& dir, const std::string& log,
                           const std::string& extra) {
  std::ifstream in(kExperiments + "/" + name + ".yaml");
  std::string yaml((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  const size_t at = yaml.find("data:");
  yaml.replace(at, yaml.find('\n', at) - at, "data: " + log);
  for (size_t p = yaml.find("../models/"); p != std::string::npos; p = yaml.find("../models/")) {
    yaml.replace(p, 10, kModels + "/");
  }
  static int count = 0;
  const std::string path = dir + "/exp" + std::to_string(count++) + ".yaml";
  std::ofstream(path) << yaml << extra;
  return path;
}

// held-out sequences through the real binary: check, fit's fit-quality table, the report's plot;
// a sequence both fitted and held out, or one the data lacks, is exit 2 naming it
TEST(SysidCliTest, ValidationSequencesAreCheckedSimulatedAndReported) {
  const std::string dir = TempDir("validation");
  const std::string log = dir + "/log.h5";
  ASSERT_EQ(Sysid("simulate " + kExperiments + "/pendulum.yaml --out " + log).code, 0);
  const std::string exp = ExperimentCopy("pendulum", dir, log, "validation: [seq2]\n");
  const CliRun check = Sysid("check " + exp);
  EXPECT_EQ(check.code, 0) << check.output;
  EXPECT_NE(check.output.find("  fitted     seq0, seq1\n  validation seq2 (held out"),
            std::string::npos)
      << check.output;
  const CliRun fit = Sysid("fit " + exp + " --out " + dir + "/out --quiet");
  EXPECT_EQ(fit.code, 0) << fit.output;
  // the table: two fitted rows and the held-out one, each "start -> estimate"
  EXPECT_NE(fit.output.find("% fit per channel"), std::string::npos) << fit.output;
  const size_t row = fit.output.find("seq2                     validation        2");
  ASSERT_NE(row, std::string::npos) << fit.output;
  EXPECT_NE(fit.output.find("seq0                     fit               2"), std::string::npos);
  EXPECT_NE(fit.output.find(" -> 99.", row), std::string::npos) << fit.output;
  // the residuals per channel: white noise simulated, so white, and the intervals as before
  EXPECT_NE(fit.output.find("residuals at the estimate"), std::string::npos) << fit.output;
  EXPECT_EQ(fit.output.find("  NO\n"), std::string::npos) << fit.output;
  EXPECT_EQ(fit.output.find("intervals from correlated"), std::string::npos) << fit.output;
  const CliRun report = Sysid("report " + dir + "/out");
  EXPECT_EQ(report.code, 0) << report.output;
  EXPECT_TRUE(fs::exists(dir + "/out/val_seq2.png"));
  EXPECT_FALSE(fs::exists(dir + "/out/seq_seq2.png"));

  const std::string both =
      ExperimentCopy("pendulum", dir, log, "sequences: [seq0, seq2]\nvalidation: [seq2]\n");
  CliRun r = Sysid("fit " + both + " --out " + dir + "/out2");
  EXPECT_EQ(r.code, 2) << r.output;
  EXPECT_NE(r.output.find("sequence 'seq2' is also fitted"), std::string::npos) << r.output;
  EXPECT_FALSE(fs::exists(dir + "/out2"));
  const std::string missing = ExperimentCopy("pendulum", dir, log, "validation: [seq7]\n");
  r = Sysid("check " + missing);
  EXPECT_EQ(r.code, 2) << r.output;
  EXPECT_NE(r.output.find("'seq7' is in none of the data files"), std::string::npos) << r.output;
  fs::remove_all(dir);
}

// --starts through the real binary: one line per finished start, the spread table, the starts in
// result.yaml and the report; --starts 0 is bad input
TEST(SysidCliTest, StartsRunSeveralFitsAndReportTheirSpread) {
  const std::string dir = TempDir("starts");
  const std::string log = dir + "/log.h5";
  ASSERT_EQ(Sysid("simulate " + kExperiments + "/spring_mass.yaml --out " + log).code, 0);
  const std::string exp = ExperimentCopy("spring_mass", dir, log, "");
  const CliRun fit = Sysid("fit " + exp + " --out " + dir + "/out --quiet --starts 3 --seed 5");
  EXPECT_EQ(fit.code, 0) << fit.output;
  for (const char* line : {"(1/3 done)", "(2/3 done)", "(3/3 done)", "3 starts (3 converged",
                           "spread over the starts"}) {
    EXPECT_NE(fit.output.find(line), std::string::npos) << line << "\n" << fit.output;
  }
  std::ifstream in(dir + "/out/result.yaml");
  const std::string yaml((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  EXPECT_NE(yaml.find("starts:\n  best: "), std::string::npos) << yaml;
  EXPECT_NE(yaml.find("\n  starts: 3\n"), std::string::npos) << yaml;  // in the solver settings
  EXPECT_NE(yaml.find("\n  seed: 5\n"), std::string::npos) << yaml;
  const CliRun report = Sysid("report " + dir + "/out");
  EXPECT_EQ(report.code, 0) << report.output;
  std::ifstream page(dir + "/out/report.html");
  const std::string html((std::istreambuf_iterator<char>(page)), std::istreambuf_iterator<char>());
  EXPECT_NE(html.find("<h2>Starts</h2>"), std::string::npos);
  const CliRun bad = Sysid("fit " + exp + " --out " + dir + "/out2 --starts 0");
  EXPECT_EQ(bad.code, 2) << bad.output;
  fs::remove_all(dir);
}

}  // namespace
