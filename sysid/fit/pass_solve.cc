// Stages 4 and 5 of a fit pass (sysid/fit/pass.h): the solve and what the result records of it.
#include <limits>
#include <map>
#include <string>

#include "sysid/fit/pass.h"
#include "sysid/solve/multiple_shooting.h"

namespace mjsysid {
namespace {

// the record's kind of Ceres' termination type
FitTermination::Kind SolverTermination(ceres::TerminationType type) {
  switch (type) {
    case ceres::CONVERGENCE:
      return FitTermination::Kind::kSolverConvergence;
    case ceres::NO_CONVERGENCE:
      return FitTermination::Kind::kIterationLimit;
    case ceres::USER_SUCCESS:
      return FitTermination::Kind::kCallbackStop;
    case ceres::USER_FAILURE:
      return FitTermination::Kind::kCallbackAbort;
    default:
      return FitTermination::Kind::kSolverFailure;
  }
}

}  // namespace

// 4. The solve. Auto's contact segments first solve with the segment states held on the data
// (sysid/solve/multiple_shooting.h, SolveWithStatesHeld): its accepted steps count as the fit's and
// its initial cost is the fit's. During the solve the trial points' first columns are computed on
// idle workers and the compressed blocks are folded ahead (sysid/solve/compressed_cost.h). Returns
// false when auto's single shooting met a Jacobian warning (the progress callback ended the solve):
// the policy refits in segments and this pass ends here.
bool FitPass::RunSolver() {
  diag_.rejected_evaluations = 0;
  diag_.jacobian_warnings.clear();
  ++solve_.cost_inputs_epoch;  // (jacobian_warnings cleared)
  ledger_.solving = true;
  // a global-stage pass holds any segments' states, when they start from the data
  const bool hold = plan_.contact_segments || (options_.continuation.hold_states &&
                                               plan_.segment_steps > 0 && StatesFromData());
  if (options_.continuation.held_only && !(hold && options_.hold_states_first && !fit_.shards)) {
    ledger_.solving = false;  // nothing to hold: a held-only pass solves nothing
    return true;
  }
  if (hold && options_.hold_states_first && !fit_.shards) {
    const ceres::Solver::Summary held = SolveWithStatesHeld(vars_, problem_.get(), solver_);
    for (size_t i = 1; i < held.iterations.size(); ++i) {
      held_accepted_ += held.iterations[i].step_is_successful ? 1 : 0;
    }
    held_initial_cost_ = held.initial_cost;
    plan_.segments.held_iterations = static_cast<int>(held.iterations.size()) - 1;
    plan_.segments.held_initial_cost = held.initial_cost;
    plan_.segments.held_final_cost = held.final_cost;
    result_.segment_reason = plan_.segments;
    if (options_.continuation.held_only) {
      summary_ = held;
      ledger_.solving = false;
      return true;
    }
  }
  solve_.cache->SetColumnsAhead(true);
  solve_.compressed = compress_ && options_.advanced.fold_ahead ? &compressed_ : nullptr;
  ceres::Solve(solver_, problem_.get(), &summary_);
  solve_.cache->SetColumnsAhead(false);
  solve_.gn_stop = nullptr;
  solve_.SetPreviousJacobian(false);
  // fired before the last Jacobian: the estimate is evaluated with the previous iterate's
  // Jacobian too (else, e.g. interrupted at that point, with its own)
  previous_jacobian_ = gn_stop_->fired_before_jacobian() && !result_.interrupted;
  ledger_.solving = false;
  // the columns computed ahead of points that were not taken (the last trial's at least)
  ledger_.Move(kPhaseTrials, kPhaseAheadUnused, solve_.cache->AheadStepsUnused());
  return !(solve_.stop_on_jacobian_warning && !diag_.jacobian_warnings.empty() &&
           !result_.interrupted);
}

// 5. What the solve gave: costs, iterations, whether it converged (Ceres or the statistical stop)
// and why it stopped, the residual count, the solve's warnings, and the estimate's values with
// their starts and bound flags (no interval yet).
void FitPass::RecordSolve() {
  result_.initial_cost = held_initial_cost_ >= 0 ? held_initial_cost_ : summary_.initial_cost;
  result_.final_cost = summary_.final_cost;
  result_.iterations = static_cast<int>(summary_.iterations.size()) - 1;
  result_.gauss_newton_converged = gn_stop_->fired() && !result_.interrupted;
  result_.converged =
      (summary_.termination_type == ceres::CONVERGENCE || result_.gauss_newton_converged) &&
      !result_.interrupted;
  // why: the statistical stop's record, else Ceres' termination type and message
  FitTermination& termination = result_.termination;
  if (result_.gauss_newton_converged) {
    termination = gn_stop_->Termination();
  } else {
    termination.kind = SolverTermination(summary_.termination_type);
  }
  termination.solver_message = summary_.message;
  if (previous_jacobian_) {
    result_.diagnostics.covariance_jacobian_iteration = gn_stop_->previous_iteration();
    result_.diagnostics.last_step_std_errors = gn_stop_->last().step_ratio;
  }
  // sharded (sysid/mpi/): the uncompressed rows, with the priors'; compressed blocks: the rows
  // they stand for
  int prior_rows = 0;
  for (const FitParameter& p : fit_.params) prior_rows += p.has_prior ? 1 : 0;
  result_.num_residuals = fit_.shards
                              ? static_cast<int>(fit_.shards->NumResiduals()) + prior_rows
                              : summary_.num_residuals + static_cast<int>(compressed_.hidden_rows);
  // a failure's message: in the status's warning (sysid/assess/fit_status.h)
  if (diag_.rejected_evaluations > 0) {
    result_.warnings.push_back(std::to_string(diag_.rejected_evaluations) +
                               " evaluation(s) rejected (trial points where the simulation "
                               "diverged or was not finite; the trust region shrank); first: " +
                               diag_.first_rejection);
  }
  if (!diag_.jacobian_warnings.empty()) {
    const auto& [segment, what] = *diag_.jacobian_warnings.begin();
    const Segment& seg = fit_.segments[segment];
    result_.warnings.push_back(
        "Jacobian not reliable in " + std::to_string(diag_.jacobian_warnings.size()) + " of " +
        std::to_string(fit_.segments.size()) + " segment(s); first: sequence '" +
        fit_.sequences[seg.seq].name + "' from step " + std::to_string(seg.k0) + ": " + what);
  }
  const int nvar = np_ + nm_;
  result_.parameters.resize(nvar);
  for (int v = 0; v < nvar; ++v) {
    ParameterEstimate& e = result_.parameters[v];
    e.name = plan_.names[v];
    e.value = v < np_ ? fit_.Physical(v, vars_.z[v]) : vars_.m[v - np_];
    e.initial = v < np_ ? fit_.params[v].initial : plan_.minitial[v - np_];
    e.at_lower = OnBound(v, e.value, true);
    e.at_upper = OnBound(v, e.value, false);
    e.std_error = e.ci95_low = e.ci95_high = std::numeric_limits<double>::quiet_NaN();
  }
}

bool FitPass::StatesFromData() const {
  const std::string& source = plan_.segments.start_source;
  return !source.empty() && source != kStartFromRollout;
}

std::vector<double> FitPass::Estimate() const {
  std::vector<double> out(static_cast<size_t>(np_));
  for (int v = 0; v < np_; ++v) out[static_cast<size_t>(v)] = fit_.Physical(v, vars_.z[v]);
  return out;
}

// whether variable v's value is on its lower or upper bound (sysid/types.h OnBound)
bool FitPass::OnBound(int v, double value, bool lower) const {
  const double lo = v < np_ ? fit_.params[v].lower : plan_.mbounds[v - np_].first;
  const double hi = v < np_ ? fit_.params[v].upper : plan_.mbounds[v - np_].second;
  return mjsysid::OnBound(value, lower ? lo : hi, lower);
}

}  // namespace mjsysid
