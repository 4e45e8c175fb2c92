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
// from EvaluateTriangle (sysid/estimate_jacobian.h): the evaluation cache holds the rollouts and
// Jacobians the solve just computed at that point, so nothing is simulated. Returns
// SOLVER_TERMINATE_SUCCESSFULLY when the test passes (Ceres reports USER_SUCCESS; fired() tells
// it from other callbacks' stops). Problem::Fit installs it only where the test is valid: single
// shooting (no continuity rows, no states eliminated elsewhere), no robust loss, no fitted
// control delay (their columns are rollouts, not cached), and auto's horizon probe measured
// bounded growth (sysid/problem.cc: on a chaotic system's rugged cost every local minimum passes
// the test); elsewhere Ceres' tolerances decide.
//
// Threads: as the evaluation cache, the thread that runs the solve. Failure: an evaluation that
// fails (a cancelled simulation) or a broken argument makes the test not pass.
#pragma once

#include <ceres/ceres.h>

#include <limits>
#include <string>
#include <vector>

#include "sysid/estimate_jacobian.h"
#include "sysid/fit_ledger.h"
#include "sysid/uncertainty.h"

namespace mjsysid {

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
};

// The test on the triangle t of [J r] (EstimateTriangle: R_aug^T R_aug = [J r]^T [J r] over
// t.rows rows, cost t.cost); bounds: t.n entries, one per column
GaussNewtonTest TestGaussNewtonStep(const EstimateTriangle& t,
                                    const std::vector<ColumnBounds>& bounds, double fraction,
                                    const UncertaintyOptions& uncertainty);

class GaussNewtonStop : public ceres::IterationCallback {
 public:
  // problem: the fit's (borrowed; every parameter block is in blocks, in the order added, as
  // EvaluateTriangle needs); fraction > 0
  // verbose: one line per test on stderr (the ratio, or why the test did not apply); ledger (the
  // fit's, borrowed, may be nullptr): the test's evaluation is charged to the phase current
  // there (it simulates nothing), not as a Jacobian of the solve
  GaussNewtonStop(const ceres::Problem* problem, std::vector<double*> blocks, double fraction,
                  const UncertaintyOptions& uncertainty, bool verbose = false,
                  FitLedger* ledger = nullptr);
  ceres::CallbackReturnType operator()(const ceres::IterationSummary& summary) override;

  bool fired() const { return fired_; }
  int tests() const { return tests_; }  // how many points were tested
  const GaussNewtonTest& last() const { return last_; }
  // the termination message of a fired test, e.g. "converged: predicted Gauss-Newton step below
  // 3 % of every standard error (largest 1.3 %, iteration 1)"
  std::string Message() const;

 private:
  const ceres::Problem* problem_;
  std::vector<double*> blocks_;
  double fraction_;
  UncertaintyOptions uncertainty_;
  bool verbose_;
  FitLedger* ledger_;
  bool fired_ = false;
  int tests_ = 0;
  int iteration_ = 0;
  GaussNewtonTest last_;
  EstimateTriangle triangle_;  // reused between iterations
  std::vector<ColumnBounds> bounds_;
};

}  // namespace mjsysid
