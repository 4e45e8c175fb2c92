// The fit's clock and its progress inside one long rollout: StepProgressEvents turns the core's
// StepProgress hook (core/simulator.h) into FitObserver::OnProgress events (sysid/fit_observer.h)
// when another tenth of a task's steps is done and at least min_seconds have passed since the task
// started or reported last: every ~10 % of a sequence's steps or every ~min_seconds
// (FitOptions::advanced.progress_seconds, 2 s), whichever is rarer, so a task shorter than
// min_seconds reports nothing. Each worker thread keeps its own task's clock (thread_local: no
// lock; the clock is read once per tenth); the observer is called from the workers.
#pragma once

#include <chrono>
#include <string>

#include "core/simulator.h"

namespace mjsysid {

class FitObserver;

// seconds since t0 on the steady clock
inline double SecondsSince(std::chrono::steady_clock::time_point t0) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
}

class StepProgressEvents : public StepProgress {
 public:
  StepProgressEvents(std::chrono::steady_clock::time_point fit_start, double min_seconds,
                     FitObserver* observer) {
    Reset(fit_start, min_seconds, observer);
  }
  // a new fit (not while a simulation runs); observer borrowed, nullptr: no events
  void Reset(std::chrono::steady_clock::time_point fit_start, double min_seconds,
             FitObserver* observer) {
    fit_start_ = fit_start;
    min_seconds_ = min_seconds;
    observer_ = observer;
  }
  void Step(const char* what, int done, int total) override;

 private:
  std::chrono::steady_clock::time_point fit_start_;
  double min_seconds_ = 0;
  FitObserver* observer_ = nullptr;
};

}  // namespace mjsysid
