// Progress inside one long rollout (core/simulator.h StepProgress, sysid/solve/progress.h
// StepProgressEvents). Core: a rollout of 1000 steps calls the hook at steps 0, 100, .., 900 and a
// directional Jacobian (with the initial state's columns) once per column at the same steps; no
// hook, no call. Fit: a fit of one long pendulum sequence with an observer
// (experiments/pendulum.yaml's truth, noise and seed; 1 x 60,000 steps, 1 iteration) reports "sim"
// lines inside the start's rollout and Jacobian, before its first iteration row, when every tenth
// may report (progress_seconds 0); the shipped short sequences (3 x 2000 steps, a few milliseconds
// each) report none at the default 2 s. No timing is asserted: the short case needs each rollout to
// stay below 2 s, which it does by three orders of magnitude.
#include <gtest/gtest.h>

#include <mutex>
#include <string>
#include <tuple>
#include <vector>

#include "core/mujoco_env.h"
#include "core/simulator.h"
#include "sysid/io/experiment.h"
#include "sysid/io/log.h"
#include "sysid/run/fit_experiment.h"
#include "sysid/run/fit_table.h"
#include "sysid/sim/simulate.h"
#include "sysid/solve/progress.h"
#include "tests/experiment_log.h"
#include "tests/file_util.h"

namespace mjsysid {
namespace {

const std::string kModels = MJSYSID_MODELS_DIR;

// every call, in order
class Recorder : public StepProgress {
 public:
  void Step(const char* what, int done, int total) override {
    std::lock_guard<std::mutex> lock(mutex_);
    calls.emplace_back(what, done, total);
  }
  std::vector<std::tuple<std::string, int, int>> calls;

 private:
  std::mutex mutex_;
};

TEST(StepProgressTest, TenthsOfRolloutsAndJacobianColumns) {
  ModelPtr m = LoadModel(kModels + "/pendulum.xml");
  Simulator sim(*m, {ParameterSpec{"joint_damping", "hinge", "", 0, ""}});
  SequenceInput seq;
  seq.x0 = sim.ReferenceState();
  seq.x0.qpos[0] = 0.4;
  seq.ctrl = RowMatrix::Zero(1000, m->nu);
  const Trajectory none = sim.Rollout(seq);  // no hook: nothing to record
  Recorder recorder;
  sim.SetStepProgress(&recorder);
  const Trajectory tr = sim.Rollout(seq);
  std::vector<std::tuple<std::string, int, int>> tenths;
  for (int k = 0; k < 1000; k += 100) tenths.emplace_back("rollout", k, 1000);
  EXPECT_EQ(recorder.calls, tenths);

  recorder.calls.clear();
  JacobianOptions jo;
  jo.mode = JacobianMode::kDirectional;
  jo.initial_state = true;
  sim.Jacobians(seq, tr, jo);
  const int columns = 1 + sim.dims().nx;  // the parameter and the initial state's
  ASSERT_EQ(static_cast<int>(recorder.calls.size()), 10 * columns);
  for (int c = 0; c < columns; ++c) {
    for (int i = 0; i < 10; ++i) {
      EXPECT_EQ(recorder.calls[c * 10 + i],
                std::make_tuple(std::string("Jacobian column"), 100 * i, 1000));
    }
  }
  sim.SetStepProgress(nullptr);
  sim.Rollout(seq);
  EXPECT_EQ(static_cast<int>(recorder.calls.size()), 10 * columns);
}

// the progress table (sysid/run/fit_table.h) of a fit of experiments/pendulum.yaml with
// `sequences` x `steps` samples, its lines joined; nothing is printed
std::string FitTableText(int sequences, int steps, double progress_seconds) {
  io::ExperimentConfig cfg =
      test::ShippedExperimentWithLog("pendulum.yaml", sequences, steps, "step_progress");
  run::BuiltProblem built = run::BuildProblem(cfg, 1);
  FitOptions options = built.options;
  std::string text;
  run::FitTable table([&text](const std::string& line) { text += line + "\n"; }, false);
  options.observer = &table;
  options.threads = 1;
  options.max_iterations = 1;
  options.advanced.progress_seconds = progress_seconds;
  built.problem->Fit(options);
  table.Flush();
  return text;
}

TEST(StepProgressTest, LongRolloutsReportTenthsShortOnesNothing) {
  const std::string long_fit = FitTableText(1, 60000, 0);
  const size_t first_iteration = long_fit.find("\n   0  ");
  ASSERT_NE(first_iteration, std::string::npos);
  const size_t rollout = long_fit.find("sim    rollout 10 % of 60000 steps");
  const size_t column = long_fit.find("sim    Jacobian column 90 % of 60000 steps");
  EXPECT_NE(rollout, std::string::npos);
  EXPECT_NE(column, std::string::npos);
  EXPECT_LT(rollout, first_iteration);
  EXPECT_LT(column, first_iteration);

  const std::string short_fit = FitTableText(3, 2000, 2.0);
  EXPECT_NE(short_fit.find("\n   0  "), std::string::npos);
  EXPECT_EQ(short_fit.find("sim    "), std::string::npos) << short_fit;
}

}  // namespace
}  // namespace mjsysid
