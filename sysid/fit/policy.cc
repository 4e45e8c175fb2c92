// Problem::Fit: the outer policy around one fit pass (sysid/fit/pass.h). Auto multiple shooting
// (FitOptions::segment_steps -1) may fit a second time, in segments:
//   - after a Jacobian warning: single shooting whose Jacobian stopped being local (the core's
//     sensitivity warning) ends its solve at once and the fit runs again in segments of the
//     length the warning implies (SegmentStepsAfterWarning); the refit is the result;
//   - after a failure: single shooting that did not converge on a system whose probe grew well
//     beyond linear is refitted in segments (SegmentStepsAfterFailure); the refit is the result
//     when it converges. Else the two are compared by a common cost: the refit's estimate
//     simulated in one piece (single shooting, a pass of no iteration) against the
//     single-shooting fit's final cost. The refit is the result when that cost is lower by more
//     than the noise explains (the single-shooting fit stopped in another minimum), else the
//     single-shooting fit stays; a warning says which and why. (A segmented cost is never
//     compared with a single-shooting one: segments restarted from the data fit it better
//     whatever the parameters.)
// The passes' records are combined as records: the refit's segment choice replaced by the
// policy's reason, traces, steps, seconds and ledger rows joined. Then the global stage
// (sysid/fit/global_stage.h) may continue from the local fit's estimate, and a fit that converged
// in segments is checked in one piece (CheckInOnePiece).
#include "sysid/fit/policy.h"

#include <algorithm>
#include <cmath>
#include <exception>
#include <limits>
#include <new>
#include <string>
#include <vector>

#include "core/text.h"
#include "sysid/assess/chi_square.h"
#include "sysid/assess/fit_status.h"
#include "sysid/fit/global_stage.h"
#include "sysid/fit/pass.h"
#include "sysid/fit/records.h"
#include "sysid/fit/restart.h"
#include "sysid/fit/subset_start.h"
#include "sysid/fit/timestep_check.h"
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

// A pass of no iteration from the physical parameter values x with every sequence simulated in
// one piece from its start (single shooting: the fit's sensors, weights and priors; measurement
// terms and control delays at their starts), assessed (stages 5-9) or only costed (its
// final_cost, seconds, steps and ledger). false when it cannot be evaluated (a simulation error);
// only std::bad_alloc propagates. The problem keeps its starts.
bool PassInOnePiece(const FitParts& parts, const FitOptions& options, const std::vector<double>& x,
                    bool assess, FitResult* out) {
  const KeepStarts keep(parts.fit);
  StartAt(parts.fit, x, false);
  FitOptions one = options;
  one.segment_steps = 0;
  one.max_iterations = 0;
  one.observer = nullptr;  // part of the fit's policy: no progress of its own
  one.on_iteration = nullptr;
  try {
    FitPass pass(parts, one);
    pass.Solve();
    if (assess) {
      pass.Assess();
    } else {
      pass.FinishRecords();
      pass.result().final_cost = pass.SolvedCost();
    }
    *out = std::move(pass.result());
    return true;
  } catch (const std::bad_alloc&) {
    throw;
  } catch (const std::exception&) {
    return false;
  }
}

// the cost of x in one piece (PassInOnePiece), whose records join *into's; +inf when it cannot be
// evaluated
double CostInOnePiece(const FitParts& parts, const FitOptions& options,
                      const std::vector<double>& x, FitResult* into) {
  FitResult piece;
  if (!PassInOnePiece(parts, options, x, false, &piece)) {
    return std::numeric_limits<double>::infinity();
  }
  AddRecords(piece, "refit's estimate in one piece", false, into);
  return piece.final_cost;
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
  const size_t np = parts.fit->params.size();
  // the common cost: the refit's estimate in one piece (not for a refit that was interrupted)
  double one_piece = std::numeric_limits<double>::infinity();
  if (refit.outcome != FitStatus::kConverged && !refit.interrupted &&
      refit.parameters.size() >= np) {
    one_piece = CostInOnePiece(parts, options, EstimateOf(refit, np), &refit);
  }
  const bool lower =
      std::isfinite(one_piece) &&
      AboveByMoreThanNoise(result.final_cost, one_piece, refit.uncertainty.residual_variance,
                           static_cast<int>(np));
  if (refit.outcome == FitStatus::kConverged || lower) {
    if (lower) {
      refit.warnings.push_back(
          "auto: the single-shooting fit ended " + std::string(FitStatusName(result.outcome)) +
          " at cost " + FormatDigits(result.final_cost, 4) + "; " + reason + " ended " +
          FitStatusName(refit.outcome) +
          ", and their estimate simulated in one piece has the lower cost " +
          FormatDigits(one_piece, 4) +
          ": the single-shooting fit had stopped in another minimum (local minimum); this "
          "result is the refit's");
    }
    // the ledger adds up to simulation_steps: the single-shooting fit's rows first
    AddRecords(result, "single-shooting fit", true, &refit);
    *mode = {steps, false};
    return refit;
  }
  result.warnings.push_back(
      "auto: " + reason + " were tried and ended " + FitStatusName(refit.outcome) +
      (std::isfinite(one_piece)
           ? "; their estimate simulated in one piece has cost " + FormatDigits(one_piece, 4) +
                 ", not below this fit's " + FormatDigits(result.final_cost, 4) +
                 " by more than the noise explains"
           : std::string()) +
      "; the single-shooting fit stays");
  AddRecords(refit, "multiple-shooting refit", false, &result);
  return std::move(result);
}

// A fit that converged in segments, simulated in one piece at its estimate (single shooting from
// each sequence's start: a pass of no iteration, assessed). Where that pass's cost is smooth (its
// interval check saw no contacts, constraint changes, kinks or flagged Jacobian: the one-piece
// rollouts follow the data as faithfully as the segments) and its residuals fail the tests of
// model_mismatch, the segments' free states absorbed an effect the model lacks: *result becomes
// model_mismatch, saying so. Measured (tests/sysid/status_test.cc): the pendulum fitted without
// its friction in 20-step segments converged at a weighted residual variance of 1.34 (the
// continuity gaps, 0.053, took up the friction); in one piece the variance is 53.8 (the rate's
// 100). Not for fits
// with measurement terms, control delays or estimated initial states (the pass would start them
// elsewhere), nor sharded ones. Its steps and time join the result's records.
void CheckInOnePiece(const FitParts& parts, const FitOptions& options, FitResult* result) {
  FitResult& r = *result;
  const size_t np = parts.fit->params.size();
  if (r.outcome != FitStatus::kConverged || r.segment_steps_used <= 0 || parts.fit->shards ||
      r.parameters.size() != np || np == 0 || options.estimate_initial_state) {
    return;
  }
  FitResult piece;
  if (!PassInOnePiece(parts, options, EstimateOf(r, np), true, &piece)) return;
  AddRecords(piece, "the estimate in one piece", false, &r);
  if (piece.interval_check.kind == IntervalCheckRecord::Kind::kRanRugged ||
      piece.interval_check.kind == IntervalCheckRecord::Kind::kNotRun) {
    return;
  }
  FitResult tested = std::move(piece);
  tested.warnings.clear();
  if (!ResidualsAboveNoise(options, &tested)) {
    // the segments' gaps, if any were warned, are no finding: say so where the warning is
    const std::string tail = kSegmentsDoNotJoinTail;
    for (std::string& w : r.warnings) {
      if (w.rfind(kSegmentsDoNotJoinWarning, 0) == 0 && w.size() > tail.size() &&
          w.compare(w.size() - tail.size(), tail.size(), tail) == 0) {
        w = w.substr(0, w.size() - tail.size()) + kSegmentsJoinWithinNoiseTail;
      }
    }
    return;
  }
  r.outcome = FitStatus::kModelMismatch;
  r.intervals_valid = false;
  std::string said;  // the failing tests' own warnings
  for (const std::string& w : tested.warnings) said += " In one piece, " + w + ".";
  r.warnings.push_back(
      "model mismatch in one piece: the fit converged in segments of " +
      std::to_string(r.segment_steps_used) +
      " steps, but its estimate simulated in one piece from each sequence's start (smooth "
      "rollouts) does not explain the data: the segments' free states absorbed an effect the "
      "model lacks (their continuity gaps are its trace); the intervals are not valid." +
      said);
}

}  // namespace

FitResult FitWithPolicy(const FitParts& parts, const FitOptions& options) {
  SubsetStartRun subset = SubsetStart(parts, options);
  LocalMode mode;
  FitResult local;
  try {
    local = LocalFit(parts, options, &mode);
  } catch (...) {
    JoinSubsetStart(parts, std::move(subset), nullptr);  // the user's starts back
    throw;
  }
  JoinSubsetStart(parts, std::move(subset), &local);
  FitResult result = GlobalStage(parts, options, mode, std::move(local));
  CheckInOnePiece(parts, options, &result);
  CheckTimestep(parts, options, &result);
  return result;
}

}  // namespace mjsysid
