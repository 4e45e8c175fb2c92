// The progress lines of a fit between its iteration lines (FitOptions::verbose), so that a long
// log is never silent: the start (rollouts and Jacobians at the initial values, per model), the
// uncertainty step (the Jacobian at the estimate), the interval check, and the progress inside
// one long rollout (StepProgressLines, below). One line each, on
// stderr, in the iteration lines' format (ProgressCallback, sysid/cost_functions.h):
//   "start  TEXT  S s", S the seconds since Problem::Fit began.
#pragma once

#include <chrono>
#include <cstdio>
#include <string>

#include "core/simulator.h"

namespace mjsysid {

inline void PrintFitProgress(const char* stage, const std::string& text,
                             std::chrono::steady_clock::time_point fit_start) {
  const double seconds =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - fit_start).count();
  std::fprintf(stderr, "%-5s  %-66s  %7.2f s\n", stage, text.c_str(), seconds);
  std::fflush(stderr);
}

// Progress inside one long rollout or Jacobian column (the core's StepProgress hook,
// core/simulator.h), installed on a verbose fit's simulators: a line
//   "sim    rollout 40 % of 1000000 steps                                 S s"
// when another tenth of a task's steps is done and at least min_seconds have passed since the
// task started or printed its last line: every ~10 % of a sequence's steps or every ~min_seconds
// (FitOptions::progress_seconds, 2 s), whichever is rarer, so a task shorter than min_seconds
// prints nothing. Each worker thread keeps its own task's clock (thread_local: no lock; the
// clock is read once per tenth); a line is one fprintf, whole under concurrent workers.
class StepProgressLines : public StepProgress {
 public:
  StepProgressLines(std::chrono::steady_clock::time_point fit_start, double min_seconds) {
    Reset(fit_start, min_seconds);
  }
  // a new fit (not while a simulation runs)
  void Reset(std::chrono::steady_clock::time_point fit_start, double min_seconds) {
    fit_start_ = fit_start;
    min_seconds_ = min_seconds;
  }
  void Step(const char* what, int done, int total) override;

 private:
  std::chrono::steady_clock::time_point fit_start_;
  double min_seconds_ = 0;
};

}  // namespace mjsysid
