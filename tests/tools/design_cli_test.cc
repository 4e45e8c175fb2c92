// `sysid design` through the real command line (issue 36): a design played through
// `simulate.excitation: {type: file}`, simulated with the experiment's noise and fitted, is
// `converged` with the truth inside the 95 % intervals, and the fit's standard errors are the
// ones the design predicted (within 20 %); progress on stderr; bad input exits 2 naming what is
// wrong.
//
// Each case: the shipped experiment's parameters, sigmas and noise; the design at the truth
// (--at-truth, as the fitted standard errors are computed at the estimate), criterion
// worst_relative_std, 200 candidates, seed 1; one simulated sequence of the design's length,
// the experiment's initial values as the fit's start.
#include <gtest/gtest.h>
#include <yaml-cpp/yaml.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <regex>
#include <string>

#include "sysid/io/result.h"
#include "tests/cli_util.h"
#include "tests/file_util.h"

namespace mjsysid {
namespace {

namespace fs = std::filesystem;
using test::Sysid;

const std::string kExperiments = MJSYSID_EXPERIMENTS_DIR;

class DesignCliTest : public ::testing::Test {
 protected:
  void SetUp() override { dir_ = test::FreshTempDir("design_cli"); }
  void TearDown() override { fs::remove_all(dir_); }

  // the shipped experiment with the model path made absolute, the log and results in the temp
  // folder, one sequence, and the excitation played from `controls`
  std::string PlayedExperiment(const std::string& name, const std::string& controls) {
    std::string yaml = test::ReadFile(kExperiments + "/" + name + ".yaml");
    yaml = std::regex_replace(yaml, std::regex("model: \\.\\./models/"),
                              "model: " + kExperiments + "/../models/");
    yaml = std::regex_replace(yaml, std::regex("data: logs/"), "data: " + dir_ + "/");
    yaml = std::regex_replace(yaml, std::regex("\n  sequences: [0-9]+"), "\n  sequences: 1");
    yaml = std::regex_replace(yaml, std::regex("\n  excitation: [^\n]*"),
                              "\n  excitation: {type: file, path: " + controls + "}");
    const std::string path = dir_ + "/" + name + "_played.yaml";
    test::WriteFile(path, yaml);
    return path;
  }

  // design, simulate, fit; the fit's result and design.yaml
  void DesignSimulateFit(const std::string& name) {
    const std::string out = dir_ + "/" + name;
    const test::CliRun d =
        Sysid("design " + kExperiments + "/" + name + ".yaml --out " + out +
              " --criterion worst_relative_std --at-truth --evaluations 200 --threads 2");
    ASSERT_EQ(d.code, 0) << d.output;
    EXPECT_NE(d.output.find("candidate   200/200"), std::string::npos) << d.output;
    const std::string exp = PlayedExperiment(name, out + "/controls.csv");
    const test::CliRun s = Sysid("simulate " + exp);
    ASSERT_EQ(s.code, 0) << s.output;
    const test::CliRun f = Sysid("fit " + exp + " --out " + out + "/fit");
    ASSERT_EQ(f.code, 0) << f.output;
    result_ = io::ReadResult(out + "/fit");
    design_ = YAML::LoadFile(out + "/design.yaml");
  }

  std::string dir_;
  io::FitResultFile result_;
  YAML::Node design_;
};

// the fit of the design's log: converged, truth inside >= 90 % of the intervals, and each fitted
// standard error within 20 % of design.yaml's predicted_std.design
void ExpectPredictedIntervals(const io::FitResultFile& r, const YAML::Node& design) {
  EXPECT_EQ(r.status, "converged");
  int inside = 0, n = 0;
  for (const ParameterEstimate& p : r.parameters) {
    ASSERT_TRUE(p.truth.has_value()) << p.name;
    ++n;
    inside += p.ci95_low <= *p.truth && *p.truth <= p.ci95_high;
    const double predicted = design["predicted_std"]["design"][p.name].as<double>();
    EXPECT_NEAR(p.std_error / predicted, 1.0, 0.2)
        << p.name << ": fitted " << p.std_error << ", predicted " << predicted;
  }
  ASSERT_GT(n, 0);
  EXPECT_GE(inside, 0.9 * n) << inside << " of " << n;
}

// measured: fitted std / predicted 0.99-1.0 for the three parameters
TEST_F(DesignCliTest, PendulumDesignFitsWithThePredictedIntervals) {
  DesignSimulateFit("pendulum");
  ExpectPredictedIntervals(result_, design_);
}

TEST_F(DesignCliTest, CartPoleDesignFitsWithThePredictedIntervals) {
  DesignSimulateFit("cartpole");
  ExpectPredictedIntervals(result_, design_);
}

TEST_F(DesignCliTest, HelpNamesTheOptions) {
  const test::CliRun r = Sysid("design --help");
  EXPECT_EQ(r.code, 0);
  for (const char* s : {"--duration", "--criterion", "--contacts", "--max-joint-speed",
                        "--range-margin", "--at-truth", "controls.csv"}) {
    EXPECT_NE(r.output.find(s), std::string::npos) << s;
  }
}

TEST_F(DesignCliTest, BadInputExitsTwoNamingWhatIsWrong) {
  const std::string pendulum = kExperiments + "/pendulum.yaml";
  // an unknown criterion
  test::CliRun r = Sysid("design " + pendulum + " --criterion a_optimal --out " + dir_ + "/x");
  EXPECT_EQ(r.code, 2) << r.output;
  EXPECT_NE(r.output.find("--criterion"), std::string::npos) << r.output;
  // a sensor without a sigma: named, with the file and line of its entry
  test::WriteFile(dir_ + "/nosigma.yaml",
                  "model: " + kExperiments +
                      "/../models/pendulum.xml\n"
                      "sensors:\n  - {name: angle}\n"
                      "parameters:\n"
                      "  - {name: damping, target: joint_damping, object: hinge, initial: 0.1}\n");
  r = Sysid("design " + dir_ + "/nosigma.yaml --out " + dir_ + "/y");
  EXPECT_EQ(r.code, 2) << r.output;
  EXPECT_NE(r.output.find("nosigma.yaml:3:"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("sensor 'angle' has no noise sigma"), std::string::npos) << r.output;
  // contacts forbidden where the model rests on the floor
  r = Sysid("design " + kExperiments + "/box_floor.yaml --contacts forbid --evaluations 2 --out " +
            dir_ + "/z");
  EXPECT_EQ(r.code, 2) << r.output;
  EXPECT_NE(r.output.find("no candidate met the constraints"), std::string::npos) << r.output;
  EXPECT_FALSE(fs::exists(dir_ + "/z/design.yaml"));
  // an output that is an input: the experiment file itself named design.yaml
  fs::create_directories(dir_ + "/in");
  std::string text = test::ReadFile(pendulum);
  text = std::regex_replace(text, std::regex("model: \\.\\./models/"),
                            "model: " + kExperiments + "/../models/");
  test::WriteFile(dir_ + "/in/design.yaml", text);
  r = Sysid("design " + dir_ + "/in/design.yaml --evaluations 2 --out " + dir_ + "/in");
  EXPECT_EQ(r.code, 2) << r.output;
  EXPECT_NE(r.output.find("design.yaml is an input of this run"), std::string::npos) << r.output;
  EXPECT_EQ(test::ReadFile(dir_ + "/in/design.yaml"), text);
}

}  // namespace
}  // namespace mjsysid
