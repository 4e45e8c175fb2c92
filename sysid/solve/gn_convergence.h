// A statistical convergence test for the solve (Bates and Watts' relative-offset criterion, in the
// form R's nls uses): stop when the Gauss-Newton step still to go is a small fraction of every
// standard error, so that the solve does not end on a trial that changes nothing statistically
// (Ceres' function tolerance needs one) after a Jacobian that confirms the point.
//
// The test, at a point with residuals r (m real rows, cost = 0.5 |r|^2, priors included) and
// Jacobian J (tangent space, n columns), both already computed by the solve:
// - the variables on a bound (OnBound, sysid/types.h: as the estimate's at_lower / at_upper) are
//   held there (the active set); the rest, F, take the Gauss-Newton step d_F = -(J_F' J_F)^-1
//   J_F' r;
// - each held variable must want to leave its bound outwards at the predicted point r + J_F d_F
//   (the gradient's sign, KKT), else the test fails (Ceres' projected steps decide);
// - the standard errors are those of the result (AnalyzeUncertaintyCompressed, sysid/
//   uncertainty.h, with the fit's UncertaintyOptions, the held variables fixed): s_i = sqrt(s^2
//   (J_F' J_F)^-1_ii), s^2 = 2 cost / (m - rank);
// - it passes when |d_i| <= fraction * s_i for every i in F. It does not apply (fails) when F is
//   empty, J_F has lost a direction (rank below |F|: a step there means nothing), or s_i is not a
//   positive finite number (noise-free data: s = 0, Ceres' tolerances decide).
// The ratios |d_i| / s_i do not depend on the columns' scaling, so tangent space is as good as
// physical units. Why the default fraction (FitOptions::gauss_newton_stop) is 0.03:
// docs/numerics.md, "Stopping".
//
// GaussNewtonStop runs the test as a ceres::IterationCallback at iteration 0 and after every
// successful step (a rejected step leaves the point, and so the answer, unchanged), with J and r
// from EvaluateTriangle (sysid/assess/estimate_jacobian.h): the evaluation cache holds the rollouts
// and Jacobians the solve just computed at that point, so nothing is simulated, and each compressed
// block writes out the fold Ceres' Jacobian evaluation at that point just made (sysid/
// compressed_cost.h, "The last fold"), so nothing is re-folded: the test folds the blocks' n + 1
// rows and analyses an (n + 1) x (n + 1) triangle. (Before the last Jacobian, below, the blocks
// fold [J_k r_{k+1}] from the cache: a fold at other inputs.) Returns
// SOLVER_TERMINATE_SUCCESSFULLY when the test passes (Ceres reports USER_SUCCESS; fired() tells
// it from other callbacks' stops). Problem::Fit installs it only where the test is valid: single
// shooting (no continuity rows, no states eliminated elsewhere), no robust loss, no fitted
// control delay (their columns are rollouts, not cached), and auto's horizon probe measured
// bounded growth (sysid/fit/pass_build.cc: on a chaotic system's rugged cost every local minimum
// passes the test); elsewhere Ceres' tolerances decide.
//
// Before the last Jacobian (TestBeforeJacobian). When Ceres accepts a step x_k -> x_{k+1} it asks
// for the Jacobians at x_{k+1}; the test above would then confirm a converged point with a
// Jacobian that serves nothing else (the covariance could use J_k). So before they are simulated
// the test is made on [J_k r_{k+1}]: the previous iterate's Jacobian (the evaluation cache keeps
// it aside) with the new point's residuals (its trial rollout, exact). It fires when
// - the test above passes on that triangle (same fraction, active set at x_{k+1}), and
// - the step just taken is small in the same standard errors: |x_{k+1,i} - x_{k,i}| <= L s_i
//   for every free variable (tangent space; L = kPreviousJacobianSteps), and no held variable
//   moved. A step beyond 2 L in x_k's standard errors is refused before the test is made.
// Why: the covariance is a linearization assumed valid over +-1 s anyway (the interval check tests
// that where the cost can be rugged), so a Jacobian taken within L s of the estimate is as good
// as the estimate's own; r_{k+1} is exact, so the predicted step sees r's nonlinearity along the
// step; what it cannot see, J's change over the step, is bounded by the step's size. L: measured,
// docs/numerics.md "Stopping". The caller (the evaluation callback, sysid/solve/cost_functions.h)
// makes the problem's cost functions answer Jacobian requests with J_k while it runs and, when it
// fires, for Ceres' request too (Ceres reads it for its gradient norm only); the next
// operator() call then ends the solve without evaluating. The covariance then comes from J_k
// with the residuals, cost and s^2 at x_{k+1} (FitResult::diagnostics.
// covariance_jacobian_iteration).
//
// Threads: as the evaluation cache, the thread that runs the solve. Failure: an evaluation that
// fails (a cancelled simulation) or a broken argument makes the test not pass.
#pragma once

#include <ceres/ceres.h>

#include <Eigen/Core>
#include <limits>
#include <string>
#include <vector>

#include "sysid/assess/estimate_jacobian.h"
#include "sysid/assess/uncertainty.h"
#include "sysid/solve/fit_ledger.h"
#include "sysid/types.h"

namespace mjsysid {

class FitObserver;  // sysid/fit_observer.h

// one column's bounds in tangent space (-inf / +inf: none) and its current value
struct ColumnBounds {
  double value = 0;
  double lower = -std::numeric_limits<double>::infinity();
  double upper = std::numeric_limits<double>::infinity();
};

struct GaussNewtonTest {
  bool applies = false;  // the test could be made (see above)
  bool passed = false;   // applies and every |d_i| <= fraction s_i
  double max_ratio = 0;  // max over F of |d_i| / s_i (when applies)
  int held = 0;          // variables held on a bound
  std::string why_not;   // when !applies: why
  // the standard errors of the test (tangent space, one per column; NaN for held ones) when it
  // applies
  Eigen::VectorXd std_error;
  // TestPreviousJacobian: max over F of |x_{k+1,i} - x_{k,i}| / s_i (when applies)
  double step_ratio = 0;
};

// the largest step, in standard errors of the estimate, over which the previous iterate's
// Jacobian stands for the estimate's (TestPreviousJacobian; measured: docs/numerics.md,
// "Stopping")
inline constexpr double kPreviousJacobianSteps = 0.5;

// The test on the triangle t of [J r] (EstimateTriangle: R_aug^T R_aug = [J r]^T [J r] over
// t.rows rows, cost t.cost); bounds: t.n entries, one per column
GaussNewtonTest TestGaussNewtonStep(const EstimateTriangle& t,
                                    const std::vector<ColumnBounds>& bounds, double fraction,
                                    const UncertaintyOptions& uncertainty);

// The test before the last Jacobian (see above) on the triangle t of [J_k r_{k+1}], the bounds at
// x_{k+1} and step = x_{k+1} - x_k (tangent space, t.n entries): TestGaussNewtonStep's, and it
// passes only if also every free |step_i| <= limit s_i and every held step_i is 0
GaussNewtonTest TestPreviousJacobian(const EstimateTriangle& t,
                                     const std::vector<ColumnBounds>& bounds,
                                     const Eigen::VectorXd& step, double fraction, double limit,
                                     const UncertaintyOptions& uncertainty);

class GaussNewtonStop : public ceres::IterationCallback {
 public:
  // problem: the fit's (borrowed; every parameter block is in blocks, in the order added, as
  // EvaluateTriangle needs); fraction > 0
  // observer (borrowed, may be nullptr): each test as an OnStepTest event (the ratio, or why the
  // test did not apply); ledger (the
  // fit's, borrowed, may be nullptr): the test's evaluation is charged to the phase current
  // there (it simulates nothing), not as a Jacobian of the solve
  GaussNewtonStop(const ceres::Problem* problem, std::vector<double*> blocks, double fraction,
                  const UncertaintyOptions& uncertainty, FitObserver* observer = nullptr,
                  FitLedger* ledger = nullptr);
  ceres::CallbackReturnType operator()(const ceres::IterationSummary& summary) override;
  // the test before the Jacobians of an accepted point (see Before the last Jacobian), at the
  // problem's current values x_{k+1}, its cost functions answering with J_k; true: it fired
  // (the next operator() call ends the solve). False when no point was tested before.
  bool TestBeforeJacobian();

  bool fired() const { return fired_; }
  // fired before the last point's Jacobian: last() holds the test on [J_k r_{k+1}]
  bool fired_before_jacobian() const { return fired_ && before_jacobian_; }
  // the iteration of the last point tested after its Jacobian (x_k above)
  int previous_iteration() const { return previous_iteration_; }
  int tests() const { return tests_; }  // how many points were tested
  const GaussNewtonTest& last() const { return last_; }
  // the termination record of a fired test (kGaussNewtonStop), whose text (TerminationText) is
  // e.g. "converged: predicted Gauss-Newton step below 3 % of every standard error (largest
  // 1.3 %, iteration 1)"
  FitTermination Termination() const;

 private:
  const ceres::Problem* problem_;
  std::vector<double*> blocks_;
  double fraction_;
  UncertaintyOptions uncertainty_;
  FitObserver* observer_;
  FitLedger* ledger_;
  bool fired_ = false;
  int tests_ = 0;
  int iteration_ = 0;
  GaussNewtonTest last_;
  EstimateTriangle triangle_;  // reused between iterations
  std::vector<ColumnBounds> bounds_;
  // the last tested point x_k, every block's values in order; empty: none yet
  std::vector<std::vector<double>> previous_;
  int previous_iteration_ = 0;    // its iteration
  bool before_jacobian_ = false;  // TestBeforeJacobian fired
  GaussNewtonTest early_;         // its test

  void FillBounds();  // bounds_ at the current values
};

}  // namespace mjsysid
