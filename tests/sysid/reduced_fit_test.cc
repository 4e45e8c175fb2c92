// Fits of shipped experiments with and without the reduced model (FitOptions::reduce_model,
// core/reduced_model.h) give the same estimate bit for bit: the reduction switches off only what
// cannot change a simulated number, so every rollout, Jacobian, cost and step of the optimiser is
// the same, and exact equality (not a tolerance) is what is claimed. Cases without contact
// (pendulum, cartpole: collision and islands off) and with contact (finger: two trees, nothing
// off; crate: islands off; hopper and walker: islands and one geom's pairs off).
// box_floor is not here: two fits of it without the reduction in one process already differ (3e-8
// relative in box_friction after 6 iterations, measured; threads 1), so its estimate cannot show
// anything; its rollouts and Jacobians are compared bit for bit in
// tests/core/reduced_model_test.cc. Data: each experiment's `simulate` block (truth, noise, seed as
// shipped) with fewer sequences and steps so that both fits take a few seconds.
#include <gtest/gtest.h>

#include <algorithm>
#include <cstdio>
#include <filesystem>
#include <string>
#include <vector>

#include "sysid/io/experiment.h"
#include "sysid/io/log.h"
#include "sysid/io/result.h"
#include "sysid/run/fit_experiment.h"
#include "sysid/sim/simulate.h"
#include "tests/experiment_log.h"
#include "tests/file_util.h"

namespace mjsysid {
namespace {

struct Case {
  std::string experiment;  // under experiments/
  int sequences, steps, iterations;
  // what the reduction must switch off
  bool contact_off, island_off;
};

class ReducedFitTest : public ::testing::TestWithParam<Case> {};

FitResult FitOnce(const io::ExperimentConfig& cfg, const Case& c, bool reduce) {
  run::BuiltProblem built = run::BuildProblem(cfg, 1);
  FitOptions options = built.options;
  options.verbose = false;
  options.max_iterations = c.iterations;
  options.reduce_model = reduce;
  options.threads = 1;
  return built.problem->Fit(options);
}

TEST_P(ReducedFitTest, SameEstimateBitForBit) {
  const Case& c = GetParam();
  io::ExperimentConfig cfg =
      test::ShippedExperimentWithLog(c.experiment, c.sequences, c.steps, "reduced_fit");

  const FitResult full = FitOnce(cfg, c, false);
  const FitResult reduced = FitOnce(cfg, c, true);
  std::printf("%s: %s; %d iterations, cost %.6g\n", c.experiment.c_str(),
              ReductionText(reduced.diagnostics.reduction).c_str(), reduced.iterations,
              reduced.final_cost);

  EXPECT_TRUE(full.diagnostics.reduction.recorded);
  EXPECT_FALSE(full.diagnostics.reduction.used);
  EXPECT_TRUE(reduced.diagnostics.reduction.used);
  const auto& off = reduced.diagnostics.reduction.disabled;
  EXPECT_EQ(std::find(off.begin(), off.end(), "contact") != off.end(), c.contact_off);
  EXPECT_EQ(std::find(off.begin(), off.end(), "island") != off.end(), c.island_off);
  EXPECT_EQ(reduced.diagnostics.reduction.guard_trips, 0);

  ASSERT_EQ(full.parameters.size(), reduced.parameters.size());
  for (size_t i = 0; i < full.parameters.size(); ++i) {
    EXPECT_EQ(full.parameters[i].value, reduced.parameters[i].value)
        << full.parameters[i].name << " relative difference "
        << (reduced.parameters[i].value - full.parameters[i].value) / full.parameters[i].value;
  }
  EXPECT_EQ(full.iterations, reduced.iterations);
  EXPECT_EQ(full.initial_cost, reduced.initial_cost);
  EXPECT_EQ(full.final_cost, reduced.final_cost);
  EXPECT_EQ(full.diagnostics.simulation_steps, reduced.diagnostics.simulation_steps);
  EXPECT_EQ(full.outcome, reduced.outcome);
  std::filesystem::remove_all(std::filesystem::path(cfg.data[0].path).parent_path());
}

// `solver.reduce_model: false` reaches the fit, and a run's result.yaml records the reduction and
// reads it back (pendulum as shipped, 3 iterations, written by RunFit into a fresh folder)
TEST(ReducedFitFilesTest, SwitchAndRecordRoundTrip) {
  const std::string dir = test::FreshTempDir("reduced_files");
  const std::string path = std::string(MJSYSID_EXPERIMENTS_DIR) + "/pendulum.yaml";
  std::string text = test::ReadFile(path);
  const std::string solver = "solver:\n";
  ASSERT_NE(text.find(solver), std::string::npos);
  EXPECT_TRUE(io::ParseExperiment(text, path).options.reduce_model);
  text.replace(text.find(solver), solver.size(), solver + "  reduce_model: false\n");
  EXPECT_FALSE(io::ParseExperiment(text, path).options.reduce_model);

  io::ExperimentConfig cfg = io::LoadExperiment(path);
  cfg.simulate.sequences = 1;
  cfg.simulate.steps = 400;
  const std::string log = dir + "/log.h5";
  cfg.data = {io::DataFile{log, {}}};
  io::WriteLog(log, sim::SimulateExperiment(cfg, sim::SimulateSettings{}));
  cfg.options.max_iterations = 3;
  run::FitRunOptions opt;
  opt.out_dir = dir + "/out";
  opt.verbose = false;
  opt.threads = 1;
  run::RunFit(cfg, opt);
  const io::FitResultFile back = io::ReadResult(opt.out_dir);
  EXPECT_TRUE(back.diagnostics.reduction.recorded);
  EXPECT_TRUE(back.diagnostics.reduction.used);
  EXPECT_EQ(back.diagnostics.reduction.disabled, (std::vector<std::string>{"contact", "island"}));
  EXPECT_EQ(back.diagnostics.reduction.collision_pairs, 0);
  EXPECT_EQ(back.diagnostics.reduction.guard_trips, 0);
  EXPECT_NE(test::ReadFile(opt.out_dir + "/result.yaml")
                .find("reduced: {used: true, collision_pairs: 0, collision_pairs_off: 0, "
                      "geoms_off: 0, disabled: [contact, island], guard_trips: 0}"),
            std::string::npos);
  std::filesystem::remove_all(dir);
}

INSTANTIATE_TEST_SUITE_P(Shipped, ReducedFitTest,
                         ::testing::Values(Case{"pendulum.yaml", 1, 800, 8, true, true},
                                           Case{"cartpole.yaml", 1, 800, 8, true, true},
                                           Case{"robust/finger.yaml", 1, 400, 5, false, false},
                                           Case{"robust/crate.yaml", 1, 400, 5, false, true},
                                           Case{"robust/hopper.yaml", 1, 400, 5, false, true},
                                           Case{"robust/walker.yaml", 1, 400, 5, false, true}),
                         [](const ::testing::TestParamInfo<Case>& p) {
                           std::string name =
                               p.param.experiment.substr(0, p.param.experiment.find('.'));
                           for (char& ch : name) {
                             if (ch == '/') ch = '_';
                           }
                           return name;
                         });

}  // namespace
}  // namespace mjsysid
