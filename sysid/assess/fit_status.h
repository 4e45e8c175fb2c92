// The verdict on a finished fit: the FitStatus (sysid/types.h) of a FitResult, decided once after
// the solve by a fit pass (sysid/fit/pass.cc, Decide).
//
// Contract: result holds the solve's outcome (converged = the optimiser's convergence,
// interrupted, initial and final cost, the estimates with their starts, the uncertainty at the
// estimate, the sequences' measured and final simulated columns). DecideFitStatus sets
// result->outcome, intervals_valid, chi2_ratio and sensor_chi2_ratio, and appends the warning that
// says what went wrong. The first that applies, in this order:
// - interrupted: result->interrupted.
// - solver_failed: Ceres ended with FAILURE (result->termination.kind kSolverFailure, its message
//   in solver_message; what SuiteSparse said is already among the warnings), whatever steps it
//   accepted before: the estimate is the last accepted point, not a fit.
// - did_not_move: no accepted step changed any estimated value, unless the solve's statistical
//   stop found the start already converged (result->gauss_newton_converged).
// - jacobian_unreliable: the core flagged a Jacobian during the solve (jacobian_warned) and the
//   cost fell by less than 5 %.
// - not_converged: the optimiser did not converge.
// - jacobian_unreliable when the core flagged the Jacobian at the estimate itself and the cost
//   did not confirm the intervals' model (jacobian_warned_at_estimate: h*|S| past
//   kSensitivityGrowthLimit, the rollouts so sensitive that the linear model may hold only far
//   below a step, nor do intervals built from it; before model_mismatch: a shorter horizon is the
//   first way out).
// - model_mismatch: options.sensors_with_sigma not empty and the weighted residual variance of
//   those sensors' columns at the estimate, sum(r^2) / (m - p) with p the rank of the Jacobian at
//   the estimate, overall or per sensor (its share of m - p), above both the chi-square quantile
//   at a one-sided false-alarm rate of 1e-6 and 2. The raw weighted residuals are tested (a
//   robust loss declares outliers, it does not make a wrong model explain the data).
//   Also for sensors without a sigma: a column whose residual RMS at the estimate is above
//   kUnexplainedNoiseFactor x the noise estimated from the log itself while its % fit is below
//   kUnexplainedFitPercent (sysid/assess/noise_estimate.h); result->sensor_noise_ratio records
//   the ratio per sensor. Each test's warning is appended whatever the verdict. A sensor without a
//   sigma whose noise cannot be estimated from the log (too few consecutive measured samples, a
//   constant column) cannot be tested: no ratio, and a warning "model check not possible: ..." with
//   its % fit (saying so when below kUnexplainedFitPercent); the verdict does not cover it.
// - jacobian_unreliable when cost_not_local: the cost at the estimate +- one standard error is
//   not what the Jacobian predicts (sysid/assess/interval_check.h) and, on rollouts that can make
//   the cost rugged, the envelope check (CheckRuggedEnvelope) did not hold either. Needs no sigmas.
// - converged otherwise; intervals_valid only then (and when the uncertainty step ran).
// After the pass, the fit policy's timestep check (sysid/fit/timestep_check.h) may turn a
// chi-square model_mismatch whose misfit is the model's discretisation into converged.
#pragma once

#include "sysid/types.h"

namespace mjsysid {

// The residual tests of model_mismatch above, alone: with sigmas the chi-square test, without them
// the test against the noise the log shows. Sets result->chi2_ratio, sensor_chi2_ratio and
// sensor_noise_ratio from result's sequences (measured and simulated_final) and parameters (their
// number, or the uncertainty's rank), appends each failing test's warning; true when one fails.
bool ResidualsAboveNoise(const FitOptions& options, FitResult* result);

// accepted_steps: the solve's successful iterations; jacobian_warned: the core flagged some
// segment's Jacobian as not reliable during the solve; cost_not_local: CheckIntervalScale found
// the cost at the estimate +- one standard error far from the Jacobian's quadratic model;
// jacobian_warned_at_estimate: the core flagged the Jacobian evaluated at the estimate (the one the
// intervals come from) and the cost along every variable did not confirm the intervals' model
// (a fit pass's stage 7; sysid/fit/pass.cc)
void DecideFitStatus(const FitOptions& options, int accepted_steps, bool jacobian_warned,
                     FitResult* result, bool cost_not_local = false,
                     bool jacobian_warned_at_estimate = false);

}  // namespace mjsysid
