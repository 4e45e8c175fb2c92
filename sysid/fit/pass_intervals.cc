// Stage 7 of a fit pass (sysid/fit/pass.h): the intervals' quadratic model against the cost.
#include <cmath>
#include <limits>
#include <string>
#include <vector>

#include "sysid/assess/interval_check.h"
#include "sysid/assess/uncertainty.h"
#include "sysid/fit/pass.h"
#include "sysid/fit_observer.h"
#include "sysid/solve/progress.h"

namespace mjsysid {

// 7. The cost one standard error away from the estimate against the Jacobian's prediction:
// contacts can make the cost jump far inside an interval (sysid/assess/interval_check.h). Along the
// simulator parameters only where the rollouts at the estimate can make the cost rugged
// (RuggedReason) or the standard error is wide; the measurement terms and control delays always.
// The triangle's rows give the same model 0.5 |r + J_v d|^2 as the residual rows. What ran and why
// goes to FitResult::interval_check (never silent); a cost that jumps marks the intervals not
// valid.
void FitPass::CheckIntervals() {
  ledger_.Enter(kPhaseIntervalCheck);
  if (options_.observer) {
    options_.observer->OnStage(FitStage::kIntervalCheck, "interval check",
                               SecondsSince(solve_.fit_start));
  }
  CostSmoothness smoothness;
  smoothness.all_rollouts = !fit_.shards;
  smoothness.jacobian_warnings = static_cast<int>(diag_.jacobian_warnings.size());
  smoothness.robust_loss = options_.loss != LossType::kNone;
  smoothness.fitted_delays = static_cast<int>(fit_.control_delay_index.size());
  for (const TermIndex& t : fit_.term_index) smoothness.fitted_delays += t.delay >= 0 ? 1 : 0;
  for (size_t g = 0; g < fit_.segments.size() && smoothness.all_rollouts; ++g) {
    const EvaluationCache::Entry& e = solve_.cache->Cached(static_cast<int>(g));
    if (e.key.empty() || e.failed) {
      smoothness.all_rollouts = false;
      break;
    }
    smoothness.steps += e.tr.T;
    for (int n : e.tr.ncon) smoothness.contact_steps += n > 0 ? 1 : 0;
    smoothness.row_changes += e.tr.solver.row_changes;
    smoothness.friction_changes += e.tr.solver.friction_changes;
    const mjModel& mm = fit_.models[fit_.segments[g].model].sim->model();
    smoothness.pgs_constraints |= mm.opt.solver == mjSOL_PGS && e.tr.solver.solved > 0;
    if (e.has_jacobians && !e.jacobians_failed) smoothness.kinks += e.s.kinks;
  }
  const std::string rugged = RuggedReason(smoothness);
  const int nvar = np_ + nm_;
  const Eigen::VectorXd& se = result_.uncertainty.std_error;
  Eigen::VectorXd se_checked = se;
  int skipped = 0;
  for (int v = 0; v < np_ && rugged.empty(); ++v) {
    if (!std::isfinite(se[v]) || !(se[v] > 0)) continue;
    if (!CheckAlongSmooth(result_.parameters[v].value, se[v])) {
      ++skipped;
      se_checked[v] = std::numeric_limits<double>::quiet_NaN();
    }
  }
  const IntervalCheck ic =
      CheckIntervalScale(r_aug_.col(nvar), r_aug_.leftCols(nvar), se_checked, plan_.names,
                         [this](int v, double delta, double* c) { return CostAt(v, delta, c); });
  IntervalCheckRecord& record = result_.interval_check;
  record.kind = !rugged.empty() ? IntervalCheckRecord::Kind::kRanRugged
                : skipped == 0  ? IntervalCheckRecord::Kind::kRanSmooth
                                : IntervalCheckRecord::Kind::kSkippedSmooth;
  record.evaluations = ic.checked;
  record.skipped = skipped;
  record.parameters = np_;
  record.rugged = rugged;
  record.dynamics_jump =
      !rugged.empty() && (smoothness.contact_steps > 0 || smoothness.row_changes > 0);
  record.wide_fraction = kSmoothRelativeStd;
  // a rugged cost: whether the Jacobian's intervals still bound the estimate (a lower point
  // within 2 standard errors, or a cost that does not rise, says no)
  if (!ic.local && !rugged.empty()) {
    const RuggedEnvelope env =
        CheckRuggedEnvelope(r_aug_.col(nvar), r_aug_.leftCols(nvar), se, plan_.names,
                            result_.uncertainty.residual_variance,
                            [this](int v, double delta, double* c) { return CostAt(v, delta, c); });
    record.evaluations += env.checked;
    if (env.valid) {
      intervals_confirmed_ = true;
      WidenIntervals(env.widen);
      record.envelope =
          "intervals from the Jacobian, " +
          (env.widest.empty() ? std::string("not widened")
                              : "widened where the cost rises slower than its model (largest: " +
                                    env.widest + ")") +
          "; the cost at +-1 and +-2 standard errors along every variable rises and is nowhere "
          "below the estimate's";
      result_.warnings.push_back(
          "the cost is rugged at the scale of the intervals (" + ic.worst +
          "): contacts make it jump where a contact comes one step earlier or later; the "
          "intervals are the Jacobian's" +
          (env.widest.empty() ? std::string() : ", widened (largest: " + env.widest + ")") +
          ", checked against the cost at +-1 and +-2 standard errors along every variable "
          "(no lower point, a rise everywhere); the check is local: they are valid when the "
          "status is converged, the fit explaining the data (docs/numerics.md, \"Contact: "
          "intervals on a rugged cost\")");
      return;
    }
    result_.warnings.push_back(
        "rugged cost: " +
        (env.lower.empty()
             ? "the cost does not rise at " + env.unbounded
             : "a point below the estimate by more than the noise explains: " + env.lower) +
        ", so the estimate is not the bottom of its intervals");
  }
  // on a cost checked as rugged the check ran along every variable with an interval
  if (ic.local && !rugged.empty()) intervals_confirmed_ = true;
  if (!ic.local) {
    cost_not_local_ = true;
    result_.interval_check.cost_not_smooth = true;
    result_.warnings.push_back(
        std::string(kCostNotSmoothWarning) + ": " + ic.worst +
        "; contacts, impacts or stick-slip make the rollouts jump when a parameter moves by less "
        "than its standard error, so the Jacobian describes the cost only very locally and the "
        "intervals are not valid (docs/numerics.md, \"Contact: a rugged cost\")");
  }
}

// the intervals (std errors, 95 % intervals, covariance) of the variables scaled by widen
void FitPass::WidenIntervals(const Eigen::VectorXd& widen) {
  mjsysid::Uncertainty& u = result_.uncertainty;
  for (Eigen::Index v = 0; v < widen.size(); ++v) {
    if (widen[v] == 1) continue;
    ParameterEstimate& e = result_.parameters[static_cast<size_t>(v)];
    e.std_error *= widen[v];
    e.ci95_low = e.value - kZ95 * e.std_error;
    e.ci95_high = e.value + kZ95 * e.std_error;
    if (v < u.std_error.size()) u.std_error[v] *= widen[v];
    if (v < u.covariance.rows()) {
      u.covariance.row(v) *= widen[v];
      u.covariance.col(v) *= widen[v];
    }
  }
}

// A fit parameter's +- delta in one batch of rollouts (2 n tasks instead of two batches of n; 3
// sequences on 2 workers: 3 rounds instead of 4); each evaluation then finds its rollouts in the
// cache. The variable is restored after the evaluation.
bool FitPass::CostAt(int v, double delta, double* cost) {
  const ParameterEstimate& e = result_.parameters[v];
  const double value = e.value + delta;
  const double lo = v < np_ ? fit_.params[v].lower : plan_.mbounds[v - np_].first;
  const double hi = v < np_ ? fit_.params[v].upper : plan_.mbounds[v - np_].second;
  if (e.at_lower || e.at_upper || value < lo || value > hi) return false;
  if (v < np_ && delta > 0) {
    const double minus = e.value - delta;
    std::vector<double> zp = vars_.z, zm = vars_.z;
    zp[v] = fit_.params[v].ToVariable(value);
    zm[v] = fit_.params[v].ToVariable(minus);
    if (minus >= lo && minus <= hi && std::isfinite(zp[v]) && std::isfinite(zm[v])) {
      std::vector<const double*> x0(fit_.segments.size());
      for (size_t s = 0; s < fit_.segments.size(); ++s)
        x0[s] = fit_.X0(vars_.states, static_cast<int>(s));
      solve_.cache->PrefetchPoints({zp.data(), zm.data()}, x0);
    }
  }
  double* slot = v < np_ ? &vars_.z[v] : &vars_.m[v - np_];
  const double saved = *slot;
  *slot = v < np_ ? fit_.params[v].ToVariable(value) : value;
  const bool ok =
      std::isfinite(*slot) && problem_->Evaluate(evaluate_, cost, nullptr, nullptr, nullptr);
  *slot = saved;
  return ok;
}

}  // namespace mjsysid
