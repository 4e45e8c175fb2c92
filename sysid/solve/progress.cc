// Progress events inside one long rollout: see sysid/progress.h.
#include "sysid/solve/progress.h"

#include "sysid/fit_observer.h"

namespace mjsysid {

void StepProgressEvents::Step(const char* what, int done, int total) {
  // this worker's task: its start (done = 0) or last event
  thread_local std::chrono::steady_clock::time_point last;
  const auto now = std::chrono::steady_clock::now();
  if (done == 0) {
    last = now;
    return;
  }
  if (std::chrono::duration<double>(now - last).count() < min_seconds_) return;
  last = now;
  if (observer_) observer_->OnProgress(what, done, total, SecondsSince(fit_start_));
}

}  // namespace mjsysid
