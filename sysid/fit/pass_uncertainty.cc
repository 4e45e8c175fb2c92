// Stage 6 of a fit pass (sysid/fit/pass.h): the Jacobian at the estimate and the covariance.
#include <Eigen/SparseCore>
#include <algorithm>
#include <map>
#include <string>
#include <vector>

#include "sysid/assess/estimate_jacobian.h"
#include "sysid/assess/uncertainty.h"
#include "sysid/fit/pass.h"
#include "sysid/fit_observer.h"
#include "sysid/solve/multiple_shooting.h"
#include "sysid/solve/progress.h"

namespace mjsysid {

// 6. The Jacobian at the estimate in physical units (tangent space for states) and the covariance
// of the estimated variables. Single shooting takes the Jacobian only as the thin-QR triangle of
// [J r], block by block (sysid/assess/estimate_jacobian.h); multiple shooting the whole sparse
// Jacobian, whose state columns are eliminated (Schur complement, AnalyzeUncertaintyReduced).
// Variables stopped on a bound are not estimated. An interrupt stops the evaluation at once (the
// simulators check the flag every step): the result keeps the estimate without intervals. Under the
// statistical stop that fired before the last Jacobian the previous iterate's Jacobian is used
// with the residuals at the estimate.
void FitPass::Uncertainty() {
  auto interrupted_now = [&] { return options_.interrupt && options_.interrupt->load(); };
  for (auto& mo : fit_.models) mo.sim->SetCancelFlag(options_.interrupt);
  evaluate_.num_threads = 1;  // as the solve
  // (sharded: the shards eliminate the states, the sharded problem is single-shooting shaped)
  for (const Segment& seg : fit_.segments) multiple_ = multiple_ || (seg.next >= 0 && !fit_.shards);
  double cost = 0;
  ceres::CRSMatrix crs;
  std::vector<double> residuals;
  EstimateTriangle triangle;
  // the core's Jacobian warnings of this evaluation alone: the Jacobian the intervals come from
  std::map<int, std::string> solve_warnings;
  std::swap(solve_warnings, diag_.jacobian_warnings);
  if (!solve_warnings.empty()) ++solve_.cost_inputs_epoch;  // the estimate's folds note theirs anew
  if (options_.observer && !interrupted_now()) {
    options_.observer->OnStage(FitStage::kUncertainty, "Jacobian at the estimate (uncertainty)",
                               SecondsSince(solve_.fit_start));
  }
  ledger_.Enter(kPhaseEstimate);
  solve_.SetPreviousJacobian(previous_jacobian_);
  const bool evaluated =
      !interrupted_now() &&
      (multiple_ ? problem_->Evaluate(evaluate_, &cost, &residuals, nullptr, &crs)
                 : EvaluateTriangle(*problem_, blocks_, &triangle));
  ledger_.Enter(kPhaseCovariance);
  solve_.SetPreviousJacobian(false);
  solve_.compressed = nullptr;
  result_.diagnostics.reused_folds = compressed_.reused_folds;
  result_.diagnostics.folds = compressed_.folds;
  result_.diagnostics.ahead_folds = compressed_.ahead_folds;
  jacobian_warned_at_estimate_ = evaluated && !diag_.jacobian_warnings.empty();
  diag_.jacobian_warnings.insert(solve_warnings.begin(), solve_warnings.end());
  for (auto& mo : fit_.models) mo.sim->SetCancelFlag(nullptr);
  if (interrupted_now()) {
    result_.interrupted = true;
    result_.converged = false;
    result_.warnings.push_back("interrupted: no uncertainty step, the estimate has no intervals");
    return;
  }
  if (!evaluated) {
    result_.warnings.push_back("the residuals could not be evaluated at the estimate");
    return;
  }
  evaluated_ = true;
  // parameters first (as Ceres ordered the blocks: z, m, states); those on a bound are fixed
  const int nvar = np_ + nm_;
  const int ncols = multiple_ ? crs.num_cols : triangle.n;
  Eigen::VectorXd values = Eigen::VectorXd::Zero(multiple_ ? nvar : ncols);
  std::vector<bool> fixed(values.size(), false);
  std::vector<std::string> all_names = plan_.names;
  for (int v = 0; v < nvar; ++v) {
    values[v] = result_.parameters[v].value;
    fixed[v] = result_.parameters[v].at_lower || result_.parameters[v].at_upper;
  }
  // r_aug_: the triangle [R q; 0 rho] of [J_p r] over the parameter columns J_p (physical
  // units), for the result's jacobian and the interval check
  RowTriangle tri(nvar + 1);
  if (multiple_) {
    RowMatrix A;
    Eigen::SparseMatrix<double> B;
    SplitJacobian(crs, nvar, &A, &B);
    for (int g = 0; g < np_; ++g) A.col(g) /= fit_.DpDz(g, vars_.z[g]);
    // the rows Ceres sees may be compressed blocks' (n + 1 each): the dof counts the real rows
    result_.uncertainty = AnalyzeUncertaintyReduced(A, B, result_.num_residuals, cost, all_names,
                                                    values, fixed, uncertainty_);
    RowMatrix rows(std::min<Eigen::Index>(A.rows(), RowTriangle::kChunkRows), nvar + 1);
    for (Eigen::Index first = 0; first < A.rows(); first += rows.rows()) {
      const Eigen::Index count = std::min<Eigen::Index>(rows.rows(), A.rows() - first);
      rows.topLeftCorner(count, nvar) = A.middleRows(first, count);
      rows.topRightCorner(count, 1) =
          Eigen::Map<const Eigen::VectorXd>(residuals.data() + first, count);
      tri.Add(rows.topRows(count));
    }
  } else {
    // the physical units of the parameter columns: a column scaling of J is one of R
    const int n = triangle.n;
    for (int g = 0; g < np_; ++g) triangle.r_aug.col(g) /= fit_.DpDz(g, vars_.z[g]);
    for (int c = nvar; c < n; ++c) all_names.push_back("x0[" + std::to_string(c - nvar) + "]");
    cost = triangle.cost;
    // residual rows less the states the shards eliminated (they enter the dof as columns)
    const long long residual_rows =
        result_.num_residuals - (fit_.shards ? fit_.shards->EliminatedColumns() : 0);
    result_.uncertainty = AnalyzeUncertaintyCompressed(
        triangle.r_aug.leftCols(n), residual_rows, cost, all_names, values, fixed, uncertainty_);
    // [J_p r]'s triangle: the parameter columns come first, so R's leading block is J_p's
    RowMatrix rows(triangle.r_aug.rows(), nvar + 1);
    rows << triangle.r_aug.leftCols(nvar), triangle.r_aug.col(n);
    tri.Add(rows);
  }
  r_aug_ = tri.R();
  // keep the parameter block of the covariance
  Eigen::MatrixXd cov = result_.uncertainty.covariance.topLeftCorner(nvar, nvar);
  result_.uncertainty.covariance = cov;
  Eigen::VectorXd se = result_.uncertainty.std_error.head(nvar);
  result_.uncertainty.std_error = se;
  result_.uncertainty.identifiable.resize(nvar);
  for (int v = 0; v < nvar; ++v) {
    ParameterEstimate& e = result_.parameters[v];
    e.std_error = se[v];
    e.identifiable = result_.uncertainty.identifiable[v];
    e.ci95_low = e.value - kZ95 * e.std_error;
    e.ci95_high = e.value + kZ95 * e.std_error;
  }
  // the result keeps J_p as its triangle R (R^T R = J_p^T J_p), not the per-sample rows
  result_.jacobian = r_aug_.topLeftCorner(std::min<Eigen::Index>(r_aug_.rows(), nvar), nvar);
}

}  // namespace mjsysid
