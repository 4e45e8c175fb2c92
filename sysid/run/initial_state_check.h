// The initial-state check: a diagnosis of a fit that ended model_mismatch while every sequence
// started from its log's first row (experiment `initial_state: {estimate: false}`, the default).
//
// Why: on a log whose states carry noise (a real robot's encoders and velocity estimates) the first
// row is one noisy sample, and the simulation cannot leave it: a pendulum started 1 % off in
// velocity keeps the wrong amplitude and phase for the whole sequence. The residuals then fail the
// chi-square test although the model lacks nothing (measured on 1 % noise copies of the shipped
// pendulum and cart-pole logs: model_mismatch at a weighted residual variance of 1.67 and 24;
// with the initial states estimated, converged in 2 iterations; docs/numerics.md, "The
// equation-error start on noisy logs").
//
// What it does: the same experiment once more with the initial states estimated, started from the
// fit's estimate (every parameter's `initial` the fitted value), without the global stage and with
// at most kInitialStateCheckIterations iterations, its progress not shown (one stage line
// "check" says it runs). When that fit converges, a warning says so with both weighted residual
// variances and how far the estimates moved in the refit's standard errors. The result stays the
// user's fit (status, estimates, intervals): the check only says which setting fixes it. A
// refit that does not converge, or fails, says nothing (the chi-square warning stands).
//
// Runs when: the fit's status is model_mismatch, the initial states were not estimated, every
// fitted sequence has logged qpos, the fit had one start and was neither resumed nor sharded
// (run::RunFit decides the last three), and the second problem's memory estimate fits in what the
// first left under the run's memory limit. Costs one more (short) fit, only then.
#pragma once

#include "sysid/io/result.h"
#include "sysid/run/fit_experiment.h"

namespace mjsysid::run {

constexpr int kInitialStateCheckIterations = 20;

// run_cfg: the experiment the fit ran; bp: its built problem; options: the fit's (threads,
// observer, interrupt); memory_left: bytes the check's problem may hold (its estimate,
// run::EstimateRunMemory, above it: no check); file: the fit's result, to which the warning is
// appended. Throws nothing but std::bad_alloc (a refit that throws says nothing).
void CheckLoggedInitialStates(const io::ExperimentConfig& run_cfg, const BuiltProblem& bp,
                              const FitOptions& options, long long memory_left,
                              io::FitResultFile* file);

}  // namespace mjsysid::run
