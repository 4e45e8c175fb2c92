// The progress lines of a long run come from the start (sysid/solve/progress.h): `sysid fit` prints
// the start's rollout and Jacobian before its first iteration line and the uncertainty step after
// its last one; `sysid simulate` names each model's rollouts before they run; --quiet silences
// them. Real binary, real files: the pendulum experiment with one 20,000-step sequence (truth
// and noise of experiments/pendulum.yaml), 2 iterations. No timing is asserted, only the order.
#include <gtest/gtest.h>

#include <fstream>
#include <sstream>
#include <string>
#include <vector>

#include "tests/cli_util.h"
#include "tests/file_util.h"

namespace mjsysid::test {
namespace {

const std::string kModels = MJSYSID_MODELS_DIR;
const std::string kExperiments = MJSYSID_EXPERIMENTS_DIR;

// the lines of text, in order
std::vector<std::string> Lines(const std::string& text) {
  std::vector<std::string> out;
  std::istringstream in(text);
  for (std::string line; std::getline(in, line);) out.push_back(line);
  return out;
}

// the index of the first line starting with prefix, or -1
int FirstLine(const std::vector<std::string>& lines, const std::string& prefix) {
  for (size_t i = 0; i < lines.size(); ++i) {
    if (lines[i].rfind(prefix, 0) == 0) return static_cast<int>(i);
  }
  return -1;
}

// experiments/pendulum.yaml with one long sequence, its log in dir, 2 iterations
std::string LongPendulum(const std::string& dir) {
  std::string yaml = ReadFile(kExperiments + "/pendulum.yaml");
  auto replace = [&yaml](const std::string& from, const std::string& to) {
    const size_t at = yaml.find(from);
    ASSERT_NE(at, std::string::npos) << from;
    yaml.replace(at, from.size(), to);
  };
  replace("../models/", kModels + "/");
  replace("data: logs/pendulum.h5", "data: " + dir + "/long.h5");
  replace("sequences: 3", "sequences: 1");
  replace("steps: 2000", "steps: 20000");
  replace("max_iterations: 50", "max_iterations: 2");
  WriteFile(dir + "/long.yaml", yaml);
  return dir + "/long.yaml";
}

TEST(ProgressCliTest, LongRunsPrintProgressFromTheStart) {
  const std::string dir = FreshTempDir("progress_cli");
  const std::string exp = LongPendulum(dir);

  // simulate: the rollout is announced (stderr), then the log is written
  const CliRun sim = SysidStderr("simulate " + exp + " --threads 1");
  ASSERT_EQ(sim.code, 0) << sim.output;
  EXPECT_EQ(FirstLine(Lines(sim.output), "  simulating  model pendulum: 1 sequence x 20000 steps"),
            0)
      << sim.output;

  // fit: start line(s) first, then the iterations, then the uncertainty step
  const CliRun fit = SysidStderr("fit " + exp + " --out " + dir + "/out --threads 1");
  const std::vector<std::string> lines = Lines(fit.output);
  const int start = FirstLine(lines, "start  rollout and Jacobian of 1 sequence, 20000 steps");
  const int header = FirstLine(lines, "iter           cost");
  const int iter0 = FirstLine(lines, "   0  ");
  const int iter2 = FirstLine(lines, "   2  ");
  const int unc = FirstLine(lines, "unc    Jacobian at the estimate (uncertainty)");
  EXPECT_EQ(start, 0) << fit.output;
  EXPECT_GT(header, start) << fit.output;
  EXPECT_EQ(iter0, header + 1) << fit.output;
  EXPECT_GT(iter2, iter0) << fit.output;
  EXPECT_GT(unc, iter2) << fit.output;
  EXPECT_GT(FirstLine(lines, "unc    interval check"), unc) << fit.output;

  // --quiet: no progress line at all
  const CliRun quiet = SysidStderr("fit " + exp + " --out " + dir + "/quiet --threads 1 --quiet");
  const std::vector<std::string> quiet_lines = Lines(quiet.output);
  EXPECT_EQ(FirstLine(quiet_lines, "start"), -1) << quiet.output;
  EXPECT_EQ(FirstLine(quiet_lines, "iter"), -1) << quiet.output;
  EXPECT_EQ(FirstLine(quiet_lines, "unc"), -1) << quiet.output;
}

}  // namespace
}  // namespace mjsysid::test
