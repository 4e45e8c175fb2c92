// The timestep check (docs/real-logs.md, "The model's timestep"): whether a fit's misfit is the
// model's discretisation, and how far the timestep moves the estimate.
//
// A robot is continuous; its model steps at dt. On a log of a robot, the residuals then carry the
// integrator's error, correlated and, for a first-order integrator, proportional to dt: the
// chi-square test fails with the sigmas the encoders state although the model lacks nothing, and
// the estimates are biased by O(dt^p) (measured on robot-style logs: 0.02-0.2 % at 2 ms, many
// standard errors). The check fits the same problem once more with every model's timestep halved,
// from the estimate (the samples at their own times, segments of the same duration), and compares:
// - the excess of the weighted residual variance over the noise, chi2 - 1, of the measures the
//   chi-square test reads (the overall ratio, each sensor's): the discretisation's share scales
//   with dt^(2p); the misfit is the timestep's when the half step leaves at most kTimestepExplains
//   of it on the worst measure and on every measure above kClearMisfit (a missing term leaves its
//   sensor's unchanged);
// - every estimate: the shift theta(dt) - theta(dt / 2), and by Richardson extrapolation the
//   timestep's bias of the estimate, beta = shift * 2^p / (2^p - 1), p the integrator's order (1:
//   Euler, implicit, implicitfast; 4: RK4).
//
// Applies (CheckTimestep) when a fit with sigmas ends model_mismatch on the chi-square test with
// residuals that are not white, FitOptions::timestep_check is on, the sequences are not sharded,
// the fit has physical parameters and its dynamics do not jump (no contacts or changing constraint
// rows at the estimate, IntervalCheckRecord::dynamics_jump: there a refit moves to another point
// of a rugged cost, which says nothing about the timestep), and the interval check did not find
// the cost not smooth at the intervals' scale (kCostNotSmoothWarning), the result's own chi-square
// test fails (not only the one-piece check of a fit in segments) and no sensor without a sigma is
// above kUnexplainedNoiseFactor x its log's noise. Then:
// - every estimate's 95 % interval is widened to cover the continuous-time value theta - beta
//   ([min(theta, theta - beta) - 1.96 s, max(..) + 1.96 s]) and ParameterEstimate::timestep_bias
//   holds beta;
// - when the timestep explains the misfit (the half-step fit's chi-square bounds that of its
//   minimum from above, converged or not; a failed or interrupted solve explains nothing), the
//   status is converged (the model lacks nothing the data show; the intervals
//   hold the timestep's bias) with a warning saying so; otherwise model_mismatch stays, with the
//   check's numbers in a warning.
// FitResult::timestep_check records what was run and found. Cost: one fit at twice the steps from
// the estimate, at most kTimestepCheckIterations iterations. Failure: a half-step fit that throws
// leaves the result as it was, with a warning.
#pragma once

#include "sysid/solve/fit_state.h"
#include "sysid/types.h"

namespace mjsysid {

// the half step must leave at most this share of the misfit's excess chi2 - 1 (a first-order
// integrator's discretisation leaves 1/4, a missing term ~1)
constexpr double kTimestepExplains = 0.5;
// a chi-square ratio above this is a misfit clearly beyond the noise: every such measure (the
// overall ratio, each sensor's), and the worst, must shrink by kTimestepExplains for the timestep
// to explain the misfit
constexpr double kClearMisfit = 2.0;
// iterations of the half-step fit (from the estimate: the shift is small)
constexpr int kTimestepCheckIterations = 10;

// the order of the integrator of m's options (1 or 4)
int IntegratorOrder(int integrator);

void CheckTimestep(const FitParts& parts, const FitOptions& options, FitResult* result);

}  // namespace mjsysid
