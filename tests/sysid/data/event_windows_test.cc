// Event windows (sysid/data/event_windows.h) end to end: the robust suite's planar hopper
// (experiments/robust/hopper.yaml: encoders, torso IMU, foot touch; kicked until it falls, so its
// foot touches down and lifts off), one sequence of 400 steps simulated from the truth with the
// experiment's noise, fitted through the runner (run::RunFit, what `sysid fit` runs) from the
// experiment's start (40 % off) under auto's contact segments for two iterations (the mask is
// decided before the fit; what it does to an estimate is measured in docs/numerics.md).
#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <string>
#include <vector>

#include "sysid/io/log.h"
#include "sysid/io/result.h"
#include "sysid/run/fit_experiment.h"
#include "sysid/sim/simulate.h"
#include "tests/file_util.h"

namespace mjsysid {
namespace {

// the hopper's experiment, one short sequence, logged in a fresh folder `name`, with event_window
// `window` and two iterations
io::ExperimentConfig Hopper(int window, const std::string& name) {
  io::ExperimentConfig cfg =
      io::LoadExperiment(std::string(MJSYSID_EXPERIMENTS_DIR) + "/robust/hopper.yaml");
  cfg.simulate.sequences = 1;
  cfg.options.event_window = window;
  cfg.options.max_iterations = 2;
  cfg.options.verbose = false;
  const std::string log_path = test::FreshTempDir("event_windows_" + name) + "/log.h5";
  cfg.data = {io::DataFile{log_path, {}}};
  io::WriteLog(log_path, sim::SimulateExperiment(cfg));
  return cfg;
}

// ... fitted by the runner
run::FitRunOutcome FitHopper(int window, const std::string& name) {
  const io::ExperimentConfig cfg = Hopper(window, name);
  run::FitRunOptions opt;
  opt.out_dir = std::filesystem::path(cfg.data[0].path).parent_path().string() + "/out";
  opt.verbose = false;
  return run::RunFit(cfg, opt);
}

// NaN cells of sensor `sensor` in the result's sequences
int NanCells(const FitResult& r, const std::string& sensor) {
  int n = 0;
  for (const SequenceResult& s : r.sequences) {
    for (size_t i = 0, col = 0; i < s.sensor_names.size(); col += s.sensor_dims[i++]) {
      if (s.sensor_names[i] != sensor) continue;
      n += static_cast<int>(s.measured.middleCols(col, s.sensor_dims[i]).array().isNaN().count());
    }
  }
  return n;
}

// With event_window 2: the torso gyro (the one fitted velocity-level sensor left: the touch and
// the accelerometer are left out whole under contact segments) loses its cells next to the foot's
// contact events, the position-level encoders none; the warning, result.yaml and the result's NaN
// cells say the same count. With 0 (the default): nothing is masked and nothing is said.
TEST(EventWindowsTest, MaskVelocityCellsNextToContactEventsAndSaySo) {
  const run::FitRunOutcome on = FitHopper(2, "on");
  ASSERT_NE(SegmentReasonText(on.file.segment_reason).find("change their contact count"),
            std::string::npos)
      << SegmentReasonText(on.file.segment_reason);
  const FitResult::EventWindows& ev = on.file.event_windows;
  EXPECT_EQ(ev.window, 2);
  EXPECT_GT(ev.events, 0);
  EXPECT_EQ(ev.sensors, (std::vector<std::string>{"torso_gyro"}));
  // each event masks at most 2 x window samples of the gyro's 3 columns
  EXPECT_GT(ev.masked, 0);
  EXPECT_LE(ev.masked, ev.events * 2 * 2 * 3);
  EXPECT_EQ(ev.masked % 3, 0);  // whole samples of the 3-axis gyro
  EXPECT_EQ(NanCells(on.file, "torso_gyro"), ev.masked);
  EXPECT_EQ(NanCells(on.file, "thigh_angle"), 0);
  EXPECT_EQ(NanCells(on.file, "pitch"), 0);
  int said = 0;
  for (const std::string& w : on.file.warnings) {
    said += w.find("event windows: " + std::to_string(ev.events) + " contact events") == 0 &&
                    w.find(std::to_string(ev.masked) + " cells") != std::string::npos
                ? 1
                : 0;
    // the event cells are not reported as unmeasured samples
    EXPECT_EQ(w.find("not measured (NaN)"), std::string::npos) << w;
  }
  EXPECT_EQ(said, 1);
  const io::FitResultFile back = io::ReadResult(on.out_dir);
  EXPECT_EQ(back.event_windows.masked, ev.masked);
  EXPECT_EQ(back.event_windows.events, ev.events);
  EXPECT_EQ(back.solver.at("event_window"), "2");

  const run::FitRunOutcome off = FitHopper(0, "off");
  EXPECT_EQ(off.file.event_windows.masked, 0);
  EXPECT_EQ(NanCells(off.file, "torso_gyro"), 0);
  for (const std::string& w : off.file.warnings) {
    EXPECT_EQ(w.find("event windows"), std::string::npos) << w;
  }
  EXPECT_EQ(test::ReadFile(off.out_dir + "/result.yaml").find("event_windows:"), std::string::npos);
}

// Each fit of one Problem decides its mask from the data as given: a second fit with the same
// window masks the same cells (not counted as unmeasured), a third with window 0 none.
TEST(EventWindowsTest, EachFitOfAProblemStartsFromTheData) {
  const io::ExperimentConfig cfg = Hopper(2, "refit");
  const run::BuiltProblem bp = run::BuildProblem(cfg);
  const FitResult first = bp.problem->Fit(cfg.options);
  const FitResult second = bp.problem->Fit(cfg.options);
  ASSERT_GT(first.event_windows.masked, 0);
  EXPECT_EQ(second.event_windows.masked, first.event_windows.masked);
  EXPECT_EQ(NanCells(second, "torso_gyro"), first.event_windows.masked);
  for (const std::string& w : second.warnings) {
    EXPECT_EQ(w.find("not measured (NaN)"), std::string::npos) << w;
  }
  FitOptions off = cfg.options;
  off.event_window = 0;
  const FitResult third = bp.problem->Fit(off);
  EXPECT_EQ(third.event_windows.masked, 0);
  EXPECT_EQ(NanCells(third, "torso_gyro"), 0);
}

}  // namespace
}  // namespace mjsysid
