// the `sysid` command line as a user runs it: subcommands, outputs and exit codes
#include <gtest/gtest.h>
#include <sys/wait.h>

#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <string>

namespace {

namespace fs = std::filesystem;

struct CliRun {
  int code;
  std::string output;  // stdout and stderr
};

// runs `sysid ARGS` and returns its exit code and output
CliRun Sysid(const std::string& args) {
  const std::string cmd = std::string(MJSYSID_SYSID_BIN) + " " + args + " 2>&1";
  FILE* pipe = popen(cmd.c_str(), "r");
  std::string out;
  char buf[4096];
  while (size_t n = fread(buf, 1, sizeof(buf), pipe)) out.append(buf, n);
  const int status = pclose(pipe);
  return {WIFEXITED(status) ? WEXITSTATUS(status) : -1, out};
}

std::string TempDir(const std::string& name) {
  const fs::path dir = fs::temp_directory_path() / ("mjsysid_cli_" + name);
  fs::remove_all(dir);
  fs::create_directories(dir);
  return dir.string();
}

const std::string kExperiments = MJSYSID_EXPERIMENTS_DIR;
const std::string kModels = MJSYSID_MODELS_DIR;

TEST(SysidCliTest, HelpListsEverySubcommand) {
  const CliRun r = Sysid("--help");
  EXPECT_EQ(r.code, 0);
  for (const char* sub : {"simulate", "fit", "report", "check", "import", "rollout"}) {
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

}  // namespace
