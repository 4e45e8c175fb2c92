// Problem::Fit: the outer policy around one fit pass (sysid/fit/pass.h). Auto multiple shooting
// (FitOptions::segment_steps -1) may fit a second time, in segments:
//   - after a Jacobian warning: single shooting whose Jacobian stopped being local (the core's
//     sensitivity warning) ends its solve at once and the fit runs again in segments of the
//     length the warning implies (SegmentStepsAfterWarning); the refit is the result;
//   - after a failure: single shooting that did not converge on a system whose probe grew well
//     beyond linear is refitted in segments (SegmentStepsAfterFailure); the refit is the result
//     when it converges, else the single-shooting fit stays, saying so.
// The passes' records are combined as records: the refit's segment choice replaced by the
// policy's reason, traces, steps, seconds and ledger rows joined. Then the global stage
// (sysid/fit/global_stage.h) may continue from the local fit's estimate.
#include "sysid/fit/policy.h"

#include <algorithm>
#include <limits>
#include <string>

#include "sysid/fit/global_stage.h"
#include "sysid/fit/pass.h"
#include "sysid/fit/records.h"
#include "sysid/fit_observer.h"
#include "sysid/solve/multiple_shooting.h"
#include "sysid/solve/progress.h"

namespace mjsysid {
namespace {

// a pass in segments of `steps` with the policy's reason as its segment choice
FitResult Refit(const FitParts& parts, const FitOptions& options, int steps,
                const std::string& reason, double seconds) {
  FitOptions segmented = options;
  segmented.segment_steps = steps;
  if (options.observer) {
    options.observer->OnStage(FitStage::kRefit, reason, seconds);
  }
  FitPass pass(parts, segmented);
  pass.Solve();  // (segment_steps set: never stops for a Jacobian warning)
  pass.Assess();
  pass.result().segment_reason.choice = reason;
  return std::move(pass.result());
}

// the local fit: one pass, and auto's refit in segments; *mode: the horizon of the result's pass
FitResult LocalFit(const FitParts& parts, const FitOptions& options, LocalMode* mode) {
  FitPass pass(parts, options);
  if (pass.Solve() == FitPass::Stop::kJacobianWarning) {
    // single shooting's Jacobian stopped being local: the refit in segments is the result
    std::string reason;
    const int steps =
        SegmentStepsAfterWarning(pass.first_jacobian_warning(), pass.plan().probe_rate, &reason);
    if (steps > 0) {
      const double first_seconds = pass.Seconds();
      FitResult refit = Refit(parts, options, steps, reason, first_seconds);
      refit.seconds += first_seconds;
      refit.trace.insert(refit.trace.begin(), pass.result().trace.begin(),
                         pass.result().trace.end());
      *mode = {steps, false};
      return refit;
    }
  }
  pass.Assess();
  FitResult& result = pass.result();
  *mode = {pass.plan().segment_steps, pass.plan().contact_segments};
  if (options.segment_steps >= 0 || pass.plan().segment_steps != 0 || result.converged ||
      result.interrupted) {
    return std::move(result);
  }
  // single shooting that did not converge on a system whose probe grew well beyond linear
  int shortest = std::numeric_limits<int>::max();
  for (const SampleGrid& g : parts.fit->grids) shortest = std::min(shortest, g.steps);
  std::string reason;
  const int steps =
      SegmentStepsAfterFailure(pass.plan().probe_growth, pass.plan().probe_rate, shortest, &reason);
  if (steps <= 0) return std::move(result);
  FitResult refit = Refit(parts, options, steps, reason, result.seconds);
  if (refit.outcome == FitStatus::kConverged) {
    // the ledger adds up to simulation_steps: the single-shooting fit's rows first
    AddRecords(result, "single-shooting fit", true, &refit);
    *mode = {steps, false};
    return refit;
  }
  result.warnings.push_back("auto: " + reason + " were tried and ended " +
                            FitStatusName(refit.outcome) + "; the single-shooting fit stays");
  AddRecords(refit, "multiple-shooting refit", false, &result);
  return std::move(result);
}

}  // namespace

FitResult FitWithPolicy(const FitParts& parts, const FitOptions& options) {
  LocalMode mode;
  FitResult local = LocalFit(parts, options, &mode);
  return GlobalStage(parts, options, mode, std::move(local));
}

}  // namespace mjsysid
