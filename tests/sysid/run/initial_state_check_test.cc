// The initial-state check (sysid/run/initial_state_check.h) through run::RunFit, on the shipped
// cart-pole experiment simulated to 3 x 2000 samples (its sensor noise as shipped: positions
// 0.001, velocities 0.01) with Gaussian noise of 1 % of each channel's standard deviation added to
// the logged qpos and qvel (std::mt19937 seed 11; seeds 12 and 13 measured alike), which are
// also each sequence's initial state. Start: the experiment's own `initial` (pole mass 0.15, cart
// damping 0.3, slide friction loss 0.1; truth 0.25, 0.7, 0.3).
#include "sysid/run/initial_state_check.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <random>
#include <string>

#include "sysid/io/log.h"
#include "sysid/sim/simulate.h"
#include "tests/experiment_log.h"

namespace mjsysid::run {
namespace {

constexpr char kWarning[] = "model mismatch from the logged initial states";

// the cart-pole experiment reading a fresh log whose states carry 1 % noise
io::ExperimentConfig NoisyStatesCartpole(const std::string& tag) {
  const std::string dir = test::FreshTempDir(tag);
  io::ExperimentConfig cfg =
      io::LoadExperiment(std::string(MJSYSID_EXPERIMENTS_DIR) + "/cartpole.yaml");
  cfg.simulate.sequences = 3;
  cfg.simulate.steps = 2000;
  cfg.options.verbose = false;
  sim::SimulateSettings settings;
  settings.threads = 1;
  io::Log log = sim::SimulateExperiment(cfg, settings);
  test::NormalNoise noise(11);
  for (io::Sequence& s : log.sequences) {
    for (RowMatrix* x : {&s.qpos, &s.qvel}) test::AddRelativeNoise(0.01, &noise, x);
  }
  cfg.data = {io::DataFile{dir + "/log.h5", {}}};
  io::WriteLog(dir + "/log.h5", log);
  cfg.output = dir + "/out";
  return cfg;
}

bool HasCheckWarning(const io::FitResultFile& f) {
  return std::any_of(f.warnings.begin(), f.warnings.end(),
                     [](const std::string& w) { return w.rfind(kWarning, 0) == 0; });
}

FitRunOutcome Fit(const io::ExperimentConfig& cfg) {
  FitRunOptions opt;
  opt.out_dir = cfg.output;
  opt.verbose = false;
  return RunFit(cfg, opt);
}

// The noisy first rows fail the chi-square test: the status stays model_mismatch (exit 3) and the
// warning names the setting; with that setting the same experiment converges within 4 standard
// errors of the truth, and the check does not run.
TEST(InitialStateCheckTest, NoisyFirstRowsNamed) {
  io::ExperimentConfig cfg = NoisyStatesCartpole("initial_state_check_noisy");
  const FitRunOutcome mismatch = Fit(cfg);
  EXPECT_EQ(mismatch.file.status, "model_mismatch");
  EXPECT_EQ(mismatch.exit_code, 3);
  EXPECT_TRUE(HasCheckWarning(mismatch.file));
  for (const std::string& w : mismatch.file.warnings) {
    if (w.rfind(kWarning, 0) == 0) std::printf("[ measured ] %s\n", w.c_str());
    // the chi-square warning names the initial states among the causes, and nothing before the
    // check's warning says the model lacks something (the timestep check only rules itself out)
    if (w.rfind("model mismatch: ", 0) == 0) {
      EXPECT_NE(w.find("the initial states (taken from the log or the model, not estimated)"),
                std::string::npos)
          << w;
    }
    EXPECT_EQ(w.find("the model lacks something"), std::string::npos) << w;
  }

  cfg.options.estimate_initial_state = true;
  cfg.output += "_estimated";
  const FitRunOutcome fixed = Fit(cfg);
  EXPECT_EQ(fixed.file.status, "converged");
  EXPECT_FALSE(HasCheckWarning(fixed.file));
  for (const ParameterEstimate& p : fixed.file.parameters) {
    ASSERT_TRUE(p.truth.has_value()) << p.name;
    std::printf("[ measured ] %-12s estimate %.5g truth %.4g std error %.3g\n", p.name.c_str(),
                p.value, *p.truth, p.std_error);
    EXPECT_LE(std::abs(p.value - *p.truth), 4 * p.std_error) << p.name;
  }
}

// A mismatch the initial states do not explain: the slide's friction loss left at the model's 0.2
// (truth 0.3, not fitted). The check runs, its refit does not converge, and nothing blames the
// first rows.
TEST(InitialStateCheckTest, ModelErrorNotBlamedOnTheFirstRows) {
  io::ExperimentConfig cfg = NoisyStatesCartpole("initial_state_check_model_error");
  cfg.parameters.erase(
      std::remove_if(cfg.parameters.begin(), cfg.parameters.end(),
                     [](const io::ParameterSpec& p) { return p.name == "slide_frictionloss"; }),
      cfg.parameters.end());
  const FitRunOutcome out = Fit(cfg);
  EXPECT_EQ(out.file.status, "model_mismatch");
  EXPECT_FALSE(HasCheckWarning(out.file));
  std::printf("[ measured ] without the friction loss: %s, weighted residual variance %.3g\n",
              out.file.status.c_str(), out.file.chi2_ratio);
}

}  // namespace
}  // namespace mjsysid::run
