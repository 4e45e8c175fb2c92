// The statistical convergence test of a solve: see sysid/gn_convergence.h.
#include "sysid/solve/gn_convergence.h"

#include <Eigen/QR>
#include <algorithm>
#include <cmath>
#include <limits>
#include <utility>

#include "core/text.h"
#include "sysid/fit_observer.h"
#include "sysid/types.h"

namespace mjsysid {
namespace {

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

// the largest |step_i| / s_i over the variables with a standard error (held ones, NaN: left out)
double StepInStandardErrors(const Eigen::VectorXd& step, const Eigen::VectorXd& std_error) {
  double ratio = 0;
  for (int i = 0; i < step.size(); ++i) {
    if (!std::isnan(std_error[i])) ratio = std::max(ratio, std::abs(step[i]) / std_error[i]);
  }
  return ratio;
}

}  // namespace

GaussNewtonTest TestGaussNewtonStep(const EstimateTriangle& t,
                                    const std::vector<ColumnBounds>& bounds, double fraction,
                                    const UncertaintyOptions& uncertainty) {
  GaussNewtonTest out;
  const int n = t.n;
  if (static_cast<int>(bounds.size()) != n || t.r_aug.cols() != n + 1) {
    out.why_not = "no Jacobian of the expected shape";
    return out;
  }
  // the active set: variables on a bound are held there (+1 lower, -1 upper, 0 free)
  std::vector<int> side(n, 0);
  std::vector<bool> held(n, false);
  std::vector<int> free;
  std::vector<std::string> names(n);
  Eigen::VectorXd values(n);
  for (int i = 0; i < n; ++i) {
    const ColumnBounds& b = bounds[i];
    side[i] = OnBound(b.value, b.lower, true) ? 1 : (OnBound(b.value, b.upper, false) ? -1 : 0);
    held[i] = side[i] != 0;
    out.held += held[i] ? 1 : 0;
    if (!held[i]) free.push_back(i);
    names[i] = "column " + std::to_string(i);
    values[i] = b.value;
  }
  if (free.empty()) {
    out.why_not = "every variable on a bound";
    return out;
  }
  // the standard errors the result would report here, and the rank decision of the uncertainty
  const RowMatrix J = t.r_aug.leftCols(n);
  const Uncertainty u =
      AnalyzeUncertaintyCompressed(J, t.rows, t.cost, names, values, held, uncertainty);
  const int nf = static_cast<int>(free.size());
  if (u.rank < nf) {
    out.why_not = "J'J of the free variables is rank-deficient";
    return out;
  }
  // the Gauss-Newton step of the free variables: min |J_F d_F + r| over the triangle's rows
  Eigen::MatrixXd JF(J.rows(), nf);
  for (int a = 0; a < nf; ++a) JF.col(a) = J.col(free[a]);
  const Eigen::VectorXd r = t.r_aug.col(n);
  const Eigen::VectorXd d = JF.colPivHouseholderQr().solve(-r);
  // every held variable must push outwards at the predicted point (gradient J_i' (r + J_F d_F):
  // >= 0 on a lower bound, <= 0 on an upper one), else it would leave its bound
  const Eigen::VectorXd predicted = r + JF * d;
  for (int i = 0; i < n; ++i) {
    if (side[i] == 0 || bounds[i].lower == bounds[i].upper) continue;
    if (side[i] * J.col(i).dot(predicted) < 0) {
      out.why_not = "a variable on its bound would leave it";
      return out;
    }
  }
  // the step against the standard errors
  out.std_error = Eigen::VectorXd::Constant(n, std::numeric_limits<double>::quiet_NaN());
  for (int a = 0; a < nf; ++a) {
    const double s = u.std_error[free[a]];
    if (!(s > 0) || !std::isfinite(s)) {
      out.why_not = "a standard error is not positive (noise-free data?)";
      return out;
    }
    out.max_ratio = std::max(out.max_ratio, std::abs(d[a]) / s);
    out.std_error[free[a]] = s;
  }
  out.applies = true;
  out.passed = out.max_ratio <= fraction;
  return out;
}

GaussNewtonTest TestPreviousJacobian(const EstimateTriangle& t,
                                     const std::vector<ColumnBounds>& bounds,
                                     const Eigen::VectorXd& step, double fraction, double limit,
                                     const UncertaintyOptions& uncertainty) {
  // the predicted Gauss-Newton step on [J_k r_{k+1}]: as at any point
  GaussNewtonTest out = TestGaussNewtonStep(t, bounds, fraction, uncertainty);
  if (!out.applies) return out;
  if (step.size() != t.n) {
    out.applies = out.passed = false;
    out.why_not = "no step of the expected size";
    return out;
  }
  // the step just taken in the same standard errors; a held variable (no standard error) must
  // not have moved
  out.step_ratio = StepInStandardErrors(step, out.std_error);
  for (int i = 0; i < t.n; ++i) {
    if (std::isnan(out.std_error[i]) && step[i] != 0) {
      out.step_ratio = std::numeric_limits<double>::infinity();
    }
  }
  out.passed = out.passed && out.step_ratio <= limit;
  return out;
}

GaussNewtonStop::GaussNewtonStop(const ceres::Problem* problem, std::vector<double*> blocks,
                                 double fraction, const UncertaintyOptions& uncertainty,
                                 FitObserver* observer, FitLedger* ledger)
    : problem_(problem),
      blocks_(std::move(blocks)),
      fraction_(fraction),
      uncertainty_(uncertainty),
      observer_(observer),
      ledger_(ledger) {}

ceres::CallbackReturnType GaussNewtonStop::operator()(const ceres::IterationSummary& summary) {
  // a rejected step left the point, and so the test's answer, as it was
  if (summary.iteration > 0 && !summary.step_is_successful) return ceres::SOLVER_CONTINUE;
  // the test before this point's Jacobian fired (Ceres evaluated J_k here): end
  iteration_ = summary.iteration;
  if (before_jacobian_) {
    fired_ = true;
    last_ = early_;
    return ceres::SOLVER_TERMINATE_SUCCESSFULLY;
  }
  ++tests_;
  // the point, for the test before the next point's Jacobian
  previous_.resize(blocks_.size());
  for (size_t b = 0; b < blocks_.size(); ++b) {
    previous_[b].assign(blocks_[b], blocks_[b] + problem_->ParameterBlockSize(blocks_[b]));
  }
  previous_iteration_ = summary.iteration;
  last_ = GaussNewtonTest();
  // J and r at the point: the evaluation cache holds what the solve computed there
  const bool solving = ledger_ && ledger_->solving;
  if (ledger_) ledger_->solving = false;
  const bool evaluated = EvaluateTriangle(*problem_, blocks_, &triangle_);
  if (ledger_) ledger_->solving = solving;
  if (!evaluated) {
    last_.why_not = "the point could not be evaluated";
    return ceres::SOLVER_CONTINUE;
  }
  FillBounds();
  last_ = TestGaussNewtonStep(triangle_, bounds_, fraction_, uncertainty_);
  if (observer_) {
    if (last_.applies) {
      observer_->OnStepTest(last_.max_ratio, false,
                            "Gauss-Newton step / std error: largest " +
                                FormatDigits(last_.max_ratio, 3) + " (stop at " +
                                FormatDigits(fraction_, 3) + ")");
    } else {
      observer_->OnStepTest(kNaN, false, "Gauss-Newton stop not tested: " + last_.why_not);
    }
  }
  if (!last_.passed) return ceres::SOLVER_CONTINUE;
  fired_ = true;
  return ceres::SOLVER_TERMINATE_SUCCESSFULLY;
}

// the columns' bounds (tangent space: a block with a manifold of another size has none)
void GaussNewtonStop::FillBounds() {
  bounds_.clear();
  for (double* b : blocks_) {
    const int size = problem_->ParameterBlockSize(b);
    const int tangent = problem_->ParameterBlockTangentSize(b);
    for (int i = 0; i < tangent; ++i) {
      ColumnBounds c;
      if (tangent == size) {
        c.value = b[i];
        c.lower = problem_->GetParameterLowerBound(b, i);
        c.upper = problem_->GetParameterUpperBound(b, i);
      }
      bounds_.push_back(c);
    }
  }
}

bool GaussNewtonStop::TestBeforeJacobian() {
  if (previous_.size() != blocks_.size() || fired_) return false;
  // the step x_{k+1} - x_k in tangent space (a block's manifold's Minus)
  int n = 0;
  for (const double* x : blocks_) n += problem_->ParameterBlockTangentSize(x);
  Eigen::VectorXd step(n);
  int column = 0;
  for (size_t b = 0; b < blocks_.size(); ++b) {
    const double* x = blocks_[b];
    const double* xk = previous_[b].data();
    const int tangent = problem_->ParameterBlockTangentSize(x);
    const ceres::Manifold* manifold = problem_->GetManifold(x);
    if (manifold) {
      if (!manifold->Minus(x, xk, step.data() + column)) return false;
    } else {
      for (int i = 0; i < tangent; ++i) step[column + i] = x[i] - xk[i];
    }
    column += tangent;
  }
  // a step beyond twice the limit in x_k's standard errors (the test after J_k) is not tested:
  // the standard errors would have to double over it (measured: within 0.2 % up to 1 standard
  // error, 58 % after 127), and the test costs a fold of every row and an SVD
  if (last_.applies && last_.std_error.size() == n) {
    const double ratio = StepInStandardErrors(step, last_.std_error);  // held at x_k: left out
    if (ratio > 2 * kPreviousJacobianSteps) {
      if (observer_) {
        observer_->OnStepTest(kNaN, true,
                              "before its Jacobian: last step " + FormatDigits(ratio, 3) +
                                  " std errors of the previous point, not tested (beyond " +
                                  FormatDigits(2 * kPreviousJacobianSteps, 3) + ")");
      }
      return false;
    }
  }
  // [J_k r_{k+1}]: the caller's cost functions answer with J_k; nothing is simulated
  const bool solving = ledger_ && ledger_->solving;
  if (ledger_) ledger_->solving = false;
  const bool evaluated = EvaluateTriangle(*problem_, blocks_, &triangle_);
  if (ledger_) ledger_->solving = solving;
  if (!evaluated) return false;
  FillBounds();
  early_ = TestPreviousJacobian(triangle_, bounds_, step, fraction_, kPreviousJacobianSteps,
                                uncertainty_);
  if (observer_ && early_.applies) {
    observer_->OnStepTest(
        early_.max_ratio, true,
        "before its Jacobian: Gauss-Newton step / std error " + FormatDigits(early_.max_ratio, 3) +
            ", last step " + FormatDigits(early_.step_ratio, 3) + " std errors (stop at " +
            FormatDigits(fraction_, 3) + " and " + FormatDigits(kPreviousJacobianSteps, 3) + ")");
  }
  before_jacobian_ = early_.passed;
  return before_jacobian_;
}

FitTermination GaussNewtonStop::Termination() const {
  FitTermination t;
  t.kind = FitTermination::Kind::kGaussNewtonStop;
  t.fraction = fraction_;
  t.largest = last_.max_ratio;
  t.iteration = iteration_;
  if (fired_before_jacobian()) {
    t.jacobian_iteration = previous_iteration_;
    t.step_std_errors = last_.step_ratio;
  }
  return t;
}

}  // namespace mjsysid
