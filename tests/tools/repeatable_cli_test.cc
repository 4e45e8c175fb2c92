// A multiple-shooting fit with parallel segment Jacobians is the same bits run to run and with
// any thread count (the state blocks' order, sysid/solve/fit_state.h StateBlocks): the pendulum
// experiment (3 sequences x 2000 steps, truth and noise of experiments/pendulum.yaml) in segments
// of 100 steps, fitted twice with 2 simulator threads and once with 1; every estimate and
// standard error in result.yaml (written with 17 significant digits, so a double round-trips)
// compared with ==, and the iteration count. (Before StateBlocks, 1 and 2 threads differed by
// 2e-9 relative here.)
#include <gtest/gtest.h>

#include <sstream>
#include <string>
#include <vector>

#include "tests/cli_util.h"
#include "tests/file_util.h"

namespace mjsysid::test {
namespace {

const std::string kModels = MJSYSID_MODELS_DIR;
const std::string kExperiments = MJSYSID_EXPERIMENTS_DIR;

// the numbers after "value:", "std:" and "iterations:" in a result.yaml, in order
std::vector<double> Numbers(const std::string& yaml) {
  std::vector<double> out;
  std::istringstream in(yaml);
  for (std::string line; std::getline(in, line);) {
    for (const std::string key : {"value: ", "std: ", "iterations: "}) {
      const size_t at = line.find(key);
      if (at != std::string::npos && line.find_first_not_of(' ') == line.find(key)) {
        out.push_back(std::stod(line.substr(at + key.size())));
      }
    }
  }
  return out;
}

TEST(RepeatableCliTest, MultipleShootingFitIsTheSameBitsRunToRunAndWithOneThread) {
  const std::string dir = FreshTempDir("repeatable_cli");
  std::string yaml = ReadFile(kExperiments + "/pendulum.yaml");
  for (const auto& [from, to] : std::vector<std::pair<std::string, std::string>>{
           {"../models/", kModels + "/"}, {"data: logs/pendulum.h5", "data: " + dir + "/log.h5"}}) {
    const size_t at = yaml.find(from);
    ASSERT_NE(at, std::string::npos) << from;
    yaml.replace(at, from.size(), to);
  }
  yaml += "multiple_shooting: {segment_steps: 100}\n";
  WriteFile(dir + "/ms.yaml", yaml);
  ASSERT_EQ(Sysid("simulate " + dir + "/ms.yaml --threads 2").code, 0);
  std::vector<std::vector<double>> runs;
  for (const auto& [out, threads] :
       std::vector<std::pair<std::string, int>>{{"/a", 2}, {"/b", 2}, {"/c", 1}}) {
    const CliRun fit = Sysid("fit " + dir + "/ms.yaml --threads " + std::to_string(threads) +
                             " --quiet --out " + dir + out);
    ASSERT_EQ(fit.code, 0) << fit.output;
    runs.push_back(Numbers(ReadFile(dir + out + "/result.yaml")));
  }
  ASSERT_GE(runs[0].size(), 7u);  // 3 values, 3 standard errors, the iterations
  for (size_t r = 1; r < runs.size(); ++r) {
    ASSERT_EQ(runs[0].size(), runs[r].size());
    for (size_t i = 0; i < runs[0].size(); ++i) EXPECT_EQ(runs[0][i], runs[r][i]) << r << " " << i;
  }
}

}  // namespace
}  // namespace mjsysid::test
