// Multi-start fits (sysid/run/multi_start.h): the spread of the starts, the best start kept, and
// the local-minimum flag on a model with known local minima (and not on one without).
#include "sysid/run/multi_start.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <atomic>
#include <cmath>
#include <filesystem>
#include <string>
#include <vector>

#include "sysid/io/log.h"
#include "sysid/run/output_folder.h"
#include "sysid/sim/simulate.h"
#include "tests/file_util.h"
#include "tests/fit_test_util.h"

namespace mjsysid::run {
namespace {

namespace fs = std::filesystem;
const std::string kExperiments = MJSYSID_EXPERIMENTS_DIR;

std::string TempDir(const std::string& name) { return test::FreshTempDir("multi_start_" + name); }

// the experiment text parsed as if in experiments/, its log simulated into dir
io::ExperimentConfig Simulated(const std::string& yaml, const std::string& dir) {
  io::ExperimentConfig cfg = io::ParseExperiment(yaml, kExperiments + "/multi_start.yaml");
  cfg.data = {io::DataFile{dir + "/log.h5", {}}};
  io::WriteLog(cfg.data[0].path, sim::SimulateExperiment(cfg, sim::SimulateSettings{}));
  cfg.options.verbose = false;
  return cfg;
}

bool HasLocalMinimaWarning(const FitResult& r) {
  for (const std::string& w : r.warnings) {
    if (w.rfind("local minima:", 0) == 0) return true;
  }
  return false;
}

TEST(MultiStartTest, StartsAreALatinHypercubeInVariableSpace) {
  // a log parameter over [0.5, 200], a plain one over [-1, 3], one without bounds (start 2)
  std::vector<FitParameter> ps = {
      FitParameter("k", {}, 3.0).Bounds(0.5, 200).Log(),
      FitParameter("b", {}, 0.0).Bounds(-1, 3),
      FitParameter("free", {}, 2.0),
  };
  const int n = 9;
  const RowMatrix s = SpreadStarts(ps, n, 7);
  ASSERT_EQ(s.rows(), n);
  // start 0 is the experiment's own
  EXPECT_EQ(s(0, 0), 3.0);
  EXPECT_EQ(s(0, 1), 0.0);
  EXPECT_EQ(s(0, 2), 2.0);
  // one start per stratum of each variable range: log(k) strata, b strata, free in [1, 3]
  const double lo[3] = {std::log(0.5), -1, 1}, hi[3] = {std::log(200.0), 3, 3};
  for (int j = 0; j < 3; ++j) {
    std::vector<int> count(n - 1, 0);
    for (int i = 1; i < n; ++i) {
      const double z = j == 0 ? std::log(s(i, j)) : s(i, j);
      ASSERT_GT(z, lo[j]);
      ASSERT_LT(z, hi[j]);
      ++count[static_cast<size_t>((z - lo[j]) / (hi[j] - lo[j]) * (n - 1))];
    }
    for (int c : count) EXPECT_EQ(c, 1) << "parameter " << j;
  }
  // deterministic for a seed, different for another
  EXPECT_EQ((SpreadStarts(ps, n, 7) - s).cwiseAbs().maxCoeff(), 0.0);
  EXPECT_GT((SpreadStarts(ps, n, 8) - s).cwiseAbs().maxCoeff(), 0.0);
}

// Free oscillation of the spring-mass (truth stiffness 6, damping 0.05; zero force from x = 0.5;
// noise 0.001 m, 0.005 m/s; 2000 steps of 0.01 s). Fitting stiffness and damping from starts
// spread over stiffness [0.5, 200] and damping [0.01, 1]: a start far from the true frequency
// converges to a local minimum where the damping goes to its bound (the oscillation damped away
// fits better than one at the wrong frequency), at a cost far above the noise.
TEST(MultiStartTest, FlagsTheLocalMinimaOfAFreeOscillation) {
  const std::string dir = TempDir("free");
  io::ExperimentConfig cfg = Simulated(R"(
model: ../models/spring_mass.xml
sensors:
  - {name: x, sigma: 0.001}
  - {name: xdot, sigma: 0.005}
parameters:
  - {name: stiffness, target: joint_stiffness, object: slide, initial: 3.0, bounds: [0.5, 200.0],
     transform: log}
  - {name: damping, target: joint_damping, object: slide, initial: 0.2, bounds: [0.01, 1.0],
     transform: log}
solver: {max_iterations: 100, starts: 8, seed: 1}
simulate:
  truth: {stiffness: 6.0, damping: 0.05}
  sequences: 1
  steps: 2000
  seed: 4
  excitation: {type: zero}
  noise: {x: 0.001, xdot: 0.005}
  initial_state: {qpos: [0.5], qvel: [0.0]}
)",
                                       dir);
  const BuiltProblem bp = BuildProblem(cfg);
  FitOptions options = bp.options;
  options.threads = 2;
  // the local fits' minima: with the global stage (sysid/fit/global_stage.h) every start ends at
  // the truth's cost (below), so the local minima are those of the stage switched off
  FitOptions global = options;
  options.global_stage = false;
  const FitResult r = FitFromStarts(bp, options, cfg.starts, cfg.start_seed, false);
  ASSERT_EQ(r.starts.size(), 8u);
  EXPECT_EQ(r.starts[0].start[0], 3.0);
  EXPECT_EQ(r.starts[0].start[1], 0.2);
  // the best start found the truth (within 4 standard errors)
  EXPECT_EQ(r.outcome, FitStatus::kConverged);
  for (const auto& [name, truth] : {std::pair{"stiffness", 6.0}, {"damping", 0.05}}) {
    const ParameterEstimate& e = test::Estimate(r, name);
    EXPECT_LT(std::abs(e.value - truth), 4 * e.std_error) << name;
  }
  for (const StartResult& s : r.starts) {
    EXPECT_GE(s.final_cost, r.final_cost);
    std::printf("[ measured ] start %-24s -> %-24s cost %-12.6g %s\n",
                (std::to_string(s.start[0]) + ", " + std::to_string(s.start[1])).c_str(),
                (std::to_string(s.estimate[0]) + ", " + std::to_string(s.estimate[1])).c_str(),
                s.final_cost, FitStatusName(s.status));
  }
  // the spread and the flag, naming the parameters
  ASSERT_EQ(r.start_spread.size(), 2u);
  EXPECT_EQ(r.start_spread[0].name, "stiffness");
  EXPECT_GT(r.start_spread[0].relative, 1.0);
  ASSERT_TRUE(HasLocalMinimaWarning(r));
  // the flagged starts say local_minimum in their records; the best and the starts at its cost
  // keep their fits' own verdicts
  const std::vector<size_t> flagged = StartsInOtherMinima(r);
  ASSERT_FALSE(flagged.empty());
  for (size_t k = 0; k < r.starts.size(); ++k) {
    const bool other = std::find(flagged.begin(), flagged.end(), k) != flagged.end();
    EXPECT_EQ(r.starts[k].status == FitStatus::kLocalMinimum, other) << "start " << k;
  }
  EXPECT_EQ(r.starts[static_cast<size_t>(r.best_start)].status, FitStatus::kConverged);
  for (const std::string& w : r.warnings) {
    if (w.rfind("local minima:", 0) == 0) {
      EXPECT_NE(w.find("stiffness"), std::string::npos) << w;
      std::printf("[ measured ] %s\n", w.c_str());
    }
  }
  fs::remove_all(dir);
  // with the global stage every start ends at the best cost: no local minimum is left to flag
  const FitResult g = FitFromStarts(bp, global, cfg.starts, cfg.start_seed, false);
  ASSERT_EQ(g.starts.size(), 8u);
  for (const StartResult& s : g.starts) {
    EXPECT_NEAR(s.final_cost, g.final_cost, 1e-3 * g.final_cost)
        << s.start[0] << ", " << s.start[1];
  }
  EXPECT_FALSE(HasLocalMinimaWarning(g));
  for (const StartResult& s : g.starts) EXPECT_NE(s.status, FitStatus::kLocalMinimum);
}

// The pendulum (experiments/pendulum.yaml, one sequence): every start spread over its bounds
// (damping [1e-4, 5], frictionloss [1e-4, 2], mass [0.05, 10], log) converges to one estimate;
// no local-minimum warning, the spread within the intervals.
TEST(MultiStartTest, NoFlagWhereEveryStartFindsTheSameMinimum) {
  const std::string dir = TempDir("pendulum");
  io::ExperimentConfig cfg = io::LoadExperiment(kExperiments + "/pendulum.yaml");
  cfg.data = {io::DataFile{dir + "/log.h5", {}}};
  io::WriteLog(cfg.data[0].path, sim::SimulateExperiment(cfg, sim::SimulateSettings{}));
  cfg.options.verbose = false;
  cfg.sequences = {io::SequenceRef{"", "seq0", {}}};
  const BuiltProblem bp = BuildProblem(cfg);
  FitOptions options = bp.options;
  options.threads = 2;
  const FitResult r = FitFromStarts(bp, options, 3, 0, false);
  ASSERT_EQ(r.starts.size(), 3u);
  EXPECT_FALSE(HasLocalMinimaWarning(r));
  for (const StartResult& s : r.starts) {
    EXPECT_EQ(s.status, FitStatus::kConverged) << s.error;
  }
  for (size_t j = 0; j < r.start_spread.size(); ++j) {
    const ParameterSpread& sp = r.start_spread[j];
    std::printf("[ measured ] %-14s spread %.3g relative (std %.3g)\n", sp.name.c_str(),
                sp.relative, r.parameters[j].std_error / std::abs(r.parameters[j].value));
    EXPECT_LT(sp.max - sp.min, 2 * 1.96 * r.parameters[j].std_error) << sp.name;
  }
  fs::remove_all(dir);
}

// a stop signal before the starts: start 0 stops after its first iteration, the others never run;
// the result says interrupted (intervals not valid) and flags no local minimum
TEST(MultiStartTest, AStopSignalStopsEveryStart) {
  const std::string dir = TempDir("interrupt");
  io::ExperimentConfig cfg = io::LoadExperiment(kExperiments + "/pendulum.yaml");
  cfg.data = {io::DataFile{dir + "/log.h5", {}}};
  io::WriteLog(cfg.data[0].path, sim::SimulateExperiment(cfg, sim::SimulateSettings{}));
  cfg.options.verbose = false;
  cfg.sequences = {io::SequenceRef{"", "seq0", {}}};
  const BuiltProblem bp = BuildProblem(cfg);
  std::atomic<bool> stop{true};
  FitOptions options = bp.options;
  options.threads = 2;
  options.interrupt = &stop;
  const FitResult r = FitFromStarts(bp, options, 4, 0, false);
  ASSERT_EQ(r.starts.size(), 4u);
  EXPECT_EQ(r.best_start, 0);
  EXPECT_EQ(r.outcome, FitStatus::kInterrupted);
  EXPECT_TRUE(r.interrupted);
  EXPECT_FALSE(r.intervals_valid);
  EXPECT_LE(r.starts[0].iterations, 1);
  for (size_t k = 1; k < 4; ++k) {
    EXPECT_EQ(r.starts[k].status, FitStatus::kInterrupted);
    EXPECT_EQ(r.starts[k].error, "not started (interrupted)");
  }
  EXPECT_FALSE(HasLocalMinimaWarning(r));
  fs::remove_all(dir);
}

// through RunFit: the starts in the result file; --resume of an interrupted fit refuses starts > 1
TEST(MultiStartTest, RunFitWritesTheStartsAndResumeRefusesThem) {
  const std::string dir = TempDir("runfit");
  io::ExperimentConfig cfg = io::LoadExperiment(kExperiments + "/pendulum.yaml");
  cfg.data = {io::DataFile{dir + "/log.h5", {}}};
  io::WriteLog(cfg.data[0].path, sim::SimulateExperiment(cfg, sim::SimulateSettings{}));
  cfg.options.verbose = false;
  cfg.sequences = {io::SequenceRef{"", "seq0", {}}};
  std::atomic<bool> stop{true};
  FitRunOptions ro;
  ro.out_dir = dir + "/out";
  ro.verbose = false;
  ro.threads = 2;
  ro.starts = 2;
  ro.interrupt = &stop;
  const FitRunOutcome out = RunFit(cfg, ro);
  EXPECT_EQ(out.file.status, "interrupted");
  EXPECT_EQ(out.exit_code, 1);
  const io::FitResultFile back = io::ReadResult(ro.out_dir);
  ASSERT_EQ(back.starts.size(), 2u);
  EXPECT_EQ(back.solver.at("starts"), "2");
  ro.resume = true;
  ro.interrupt = nullptr;
  EXPECT_THROW(RunFit(cfg, ro), OutputError);
  ro.starts = 1;  // one start resumes
  EXPECT_EQ(RunFit(cfg, ro).exit_code, 0);
  fs::remove_all(dir);
}

}  // namespace
}  // namespace mjsysid::run
