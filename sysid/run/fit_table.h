// A fit's events as text (sysid/fit_observer.h): the front ends' progress output. FitTable formats
// every event as lines and hands each to `write` (the command line writes them to stderr, the
// Python module to its stderr); it prints nothing itself.
//
// The iterations form one Ceres-like table, a header and one row per iteration:
//   iter      cost         |step|   |gradient|   step/std      time
//      0   1.234568e+03        -      3.25e+02       0.41      0.02 s
//      1   1.102000e+01    4.10e-01   2.10e+01       0.03      0.05 s
//      2   1.102000e+01    1.20e-03   2.00e+00         -       0.07 s  rejected
// step/std: the predicted Gauss-Newton step in standard errors where the statistical stop tested
// it (sysid/solve/gn_convergence.h; with the iterate's own Jacobian, or before it with the previous
// one), "-" where not. A stage opens with a line of its own
//   "start  rollout and Jacobian of 3 sequences, 6000 steps                   0.01 s"
// ("start", "refit", "unc" for the uncertainty step and the interval check, "sim" for progress
// inside a long rollout), warnings read "sysid fit: warning: TEXT", and a multi-start run gives
// one line per finished start. Verbose adds the statistical stop's explanation under each row.
// Thread-safe: OnProgress and OnStartDone come from worker threads.
#pragma once

#include <functional>
#include <limits>
#include <mutex>
#include <optional>
#include <string>

#include "sysid/fit_observer.h"

namespace mjsysid::run {

class FitTable : public FitObserver {
 public:
  FitTable(std::function<void(const std::string& line)> write, bool verbose)
      : write_(std::move(write)),
        verbose_(verbose),
        next_ratio_(std::numeric_limits<double>::quiet_NaN()) {}
  ~FitTable() override { Flush(); }

  void OnStage(FitStage stage, const std::string& text, double seconds) override;
  void OnIteration(const IterationInfo& info) override;
  void OnStepTest(double step_std_errors, bool before_jacobian, const std::string& text) override;
  void OnProgress(const char* what, int done, int total, double seconds) override;
  void OnWarning(const std::string& text) override;
  void OnStartDone(int k, int done, int total, const StartResult& r) override;
  // writes the row held back for its step/std column (call when the fit has returned)
  void Flush();

 private:
  void FlushLocked();
  void Write(const std::string& line) { write_(line); }

  std::function<void(const std::string&)> write_;
  bool verbose_;
  std::mutex mutex_;
  bool header_ = false;  // the table's header is written (a stage line starts a new table)
  std::optional<IterationInfo> row_;  // the last iteration, until its step test or the next event
  double row_ratio_ = 0;              // its step/std (NaN: not tested)
  double next_ratio_;                 // the next row's, tested before its Jacobian (NaN: none)
};

}  // namespace mjsysid::run
