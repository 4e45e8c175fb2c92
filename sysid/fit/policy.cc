// Problem::Fit: the outer policy around one fit pass (sysid/fit/pass.h). Auto multiple shooting
// (FitOptions::segment_steps -1) may fit a second time, in segments:
//   - after a Jacobian warning: single shooting whose Jacobian stopped being local (the core's
//     sensitivity warning) ends its solve at once and the fit runs again in segments of the
//     length the warning implies (SegmentStepsAfterWarning); the refit is the result;
//   - after a failure: single shooting that did not converge on a system whose probe grew well
//     beyond linear is refitted in segments (SegmentStepsAfterFailure); the refit is the result
//     when it converges, else the single-shooting fit stays, saying so.
// The passes' records are combined as records: the refit's segment choice replaced by the
// policy's reason, traces, steps, seconds and ledger rows joined.
#include "sysid/fit/policy.h"

#include <algorithm>
#include <limits>
#include <string>

#include "sysid/fit/pass.h"
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

// each ledger row of r as part of `what` (e.g. "single-shooting fit: solve: Jacobians")
void PrefixLedger(const std::string& what, FitResult* r) {
  for (LedgerRow& row : r->diagnostics.ledger) row.phase = what + ": " + row.phase;
}

}  // namespace

FitResult FitWithPolicy(const FitParts& parts, const FitOptions& options) {
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
      return refit;
    }
  }
  pass.Assess();
  FitResult& result = pass.result();
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
    refit.seconds += result.seconds;
    refit.diagnostics.simulation_steps += result.diagnostics.simulation_steps;
    // the ledger adds up to simulation_steps: the single-shooting fit's rows first
    PrefixLedger("single-shooting fit", &result);
    std::vector<LedgerRow>& ledger = refit.diagnostics.ledger;
    ledger.insert(ledger.begin(), result.diagnostics.ledger.begin(),
                  result.diagnostics.ledger.end());
    refit.trace.insert(refit.trace.begin(), result.trace.begin(), result.trace.end());
    return refit;
  }
  result.warnings.push_back("auto: " + reason + " were tried and ended " +
                            FitStatusName(refit.outcome) + "; the single-shooting fit stays");
  result.seconds += refit.seconds;
  result.diagnostics.simulation_steps += refit.diagnostics.simulation_steps;
  PrefixLedger("multiple-shooting refit", &refit);
  std::vector<LedgerRow>& ledger = result.diagnostics.ledger;
  ledger.insert(ledger.end(), refit.diagnostics.ledger.begin(), refit.diagnostics.ledger.end());
  return std::move(result);
}

}  // namespace mjsysid
