// The progress lines inside one long rollout: see sysid/progress.h.
#include "sysid/progress.h"

namespace mjsysid {

void StepProgressLines::Step(const char* what, int done, int total) {
  // this worker's task: its start (done = 0) or last line
  thread_local std::chrono::steady_clock::time_point last;
  const auto now = std::chrono::steady_clock::now();
  if (done == 0) {
    last = now;
    return;
  }
  if (std::chrono::duration<double>(now - last).count() < min_seconds_) return;
  last = now;
  const long long percent = 100LL * done / total;
  PrintFitProgress("sim",
                   std::string(what) + " " + std::to_string(percent) + " % of " +
                       std::to_string(total) + " steps",
                   fit_start_);
}

}  // namespace mjsysid
