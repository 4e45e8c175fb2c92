// One pass of a fit (sysid/fit/pass.h): the sequence of stages, the start (stage 1) and the
// decision (stage 9).
#include "sysid/fit/pass.h"

#include <algorithm>
#include <string>
#include <vector>

#include "core/text.h"
#include "sysid/assess/fit_status.h"
#include "sysid/solve/progress.h"
#include "sysid/solve/quiet_libraries.h"

namespace mjsysid {

FitPass::FitPass(const FitParts& parts, const FitOptions& options)
    : parts_(parts),
      fit_(*parts.fit),
      vars_(*parts.vars),
      diag_(*parts.diag),
      solve_(*parts.solve),
      options_(options),
      start_(std::chrono::steady_clock::now()),
      ledger_(
          [fit = parts.fit] {
            long long steps = 0;
            for (const auto& mo : fit->models) steps += mo.Steps();
            return steps;
          },
          [fit = parts.fit] {
            // the task model's critical path at 2 workers (core/thread_pool.h)
            long long steps = 0;
            for (const auto& mo : fit->models) steps += mo.CriticalSteps();
            return steps;
          }) {
  // the time inside the simulators' batches (serial time = the rest)
  ledger_.MeasureBatches([fit = parts.fit] {
    PoolTime sum;
    for (const auto& mo : fit->models) sum += mo.Time();
    return sum;
  });
  solve_.ledger = &ledger_;
}

FitPass::~FitPass() {
  solve_.ledger = nullptr;
  solve_.compressed = nullptr;
}

double FitPass::Seconds() const { return SecondsSince(start_); }

const std::string& FitPass::first_jacobian_warning() const {
  return diag_.jacobian_warnings.begin()->second;
}

FitPass::Stop FitPass::Solve() {
  Start();
  BuildCeres();
  Configure();
  return RunSolver() ? Stop::kNone : Stop::kJacobianWarning;
}

void FitPass::Assess() {
  RecordSolve();
  Uncertainty();
  if (evaluated_) CheckIntervals();
  FinalSignals();
  Residuals();
  Decide();
}

// 1. the equation-error starts, the prepared fit, and what the result knows before the solve
void FitPass::Start() {
  ledger_.Enter(kPhaseAutoStart);
  solve_.fit_start = start_;
  // the progress events inside long rollouts (PrepareFit installs them on the simulators)
  if (!solve_.step_progress) {
    solve_.step_progress = std::make_unique<StepProgressEvents>(start_, 0, nullptr);
  }
  solve_.step_progress->Reset(start_, options_.advanced.progress_seconds, options_.observer);
  const std::vector<std::string> start_notes = SolveAutoStarts(&fit_, options_.threads);
  ledger_.Enter(kPhasePrepare);
  plan_ = PrepareFit(parts_, options_);
  ledger_.Enter(kPhaseSetup);
  np_ = static_cast<int>(fit_.params.size());
  nm_ = static_cast<int>(vars_.m.size());
  result_.diagnostics.jacobian_mode = plan_.jacobian_mode;
  result_.segment_steps_used = plan_.segment_steps;
  result_.segment_reason = plan_.segments;
  result_.event_windows = plan_.event_windows;
  result_.warnings = fit_.prepare_warnings;
  result_.warnings.insert(result_.warnings.end(), start_notes.begin(), start_notes.end());
  // a start on a bound: the first step may leave the bound at once or never (a projected
  // gradient pointing outwards)
  for (const FitParameter& p : fit_.params) {
    if (p.initial == p.lower || p.initial == p.upper) {
      result_.warnings.push_back("parameter '" + p.name + "' starts on its " +
                                 (p.initial == p.lower ? "lower" : "upper") + " bound " +
                                 FormatDigits(p.initial, 3) +
                                 ": start inside the bounds, or the fit may not leave it");
    }
  }
}

// 10. the verdict (sysid/assess/fit_status.h) from the accepted steps, the Jacobian warnings and
// the chi-square; the step count, the reduced model, the ledger and the time
void FitPass::Decide() {
  int accepted_steps = held_accepted_;
  for (size_t i = 1; i < summary_.iterations.size(); ++i) {
    accepted_steps += summary_.iterations[i].step_is_successful ? 1 : 0;
  }
  // what SuiteSparse printed during the solve and the uncertainty step (captured, never on the
  // terminal: sysid/solve/quiet_libraries.h), as one warning
  const std::vector<std::string> library = TakeThirdPartyMessages();
  if (!library.empty()) {
    std::string said;
    for (const std::string& line : library) said += (said.empty() ? "" : " | ") + line;
    result_.warnings.push_back("the sparse linear algebra library (SuiteSparse) said: " + said);
  }
  // the core's flag on the Jacobian at the estimate says its linear model may hold only far below
  // the intervals; the cost evaluated along every variable at +-1 (and +-2) standard errors
  // measures that directly, and where it confirmed the model the flag decides nothing (measured:
  // the outside hopper, h*|S| 0.018 in 7 of 200 segments, every truth inside its interval)
  const bool flagged = jacobian_warned_at_estimate_ && !intervals_confirmed_;
  if (jacobian_warned_at_estimate_ && intervals_confirmed_) {
    result_.warnings.push_back(
        "the core flagged the Jacobian at the estimate (h*|S| > 1e-2: the rollouts are very "
        "sensitive to the parameters there), and the cost evaluated at +-1 and +-2 standard "
        "errors along every variable confirmed the intervals' model, so the status does not "
        "rest on that flag");
  }
  DecideFitStatus(options_, accepted_steps, !diag_.jacobian_warnings.empty(), &result_,
                  cost_not_local_, flagged);
  FinishRecords();
  // what the reduced models switched off, summed over the models
  FitResult::Diagnostics::Reduction& r = result_.diagnostics.reduction;
  r = FitResult::Diagnostics::Reduction();
  r.recorded = true;
  r.used = options_.reduce_model;
  for (const auto& mo : fit_.models) {
    const ModelReduction& mr = mo.sim->reduction();
    r.collision_pairs += mr.candidate_pairs;
    r.collision_pairs_off += mr.pairs_off;
    r.geoms_off += static_cast<int>(mr.geoms_off.size());
    r.guard_trips += mo.sim->ReductionTrips();
    for (const std::string& name : DisabledNames(mr.disable)) {
      if (std::find(r.disabled.begin(), r.disabled.end(), name) == r.disabled.end()) {
        r.disabled.push_back(name);
      }
    }
  }
}

void FitPass::FinishRecords() {
  if (result_.iterations == 0)
    result_.iterations = static_cast<int>(summary_.iterations.size()) - 1;
  result_.diagnostics.simulation_steps = 0;
  for (const auto& mo : fit_.models) result_.diagnostics.simulation_steps += mo.sim->StepCount();
  result_.diagnostics.ledger = ledger_.Finish();
  result_.seconds = Seconds();
}

}  // namespace mjsysid
