// How a fit reports while it runs. The library never prints: Problem::Fit (and the experiment
// runner, sysid/run/) send events to a FitObserver, and the caller decides what to show. The
// command line formats them as one Ceres-like table and a summary (tools/fit_table.h); the Python
// package turns them into callbacks and `warnings`; a library user may ignore them (no observer).
//
// Events, in the order a fit sends them:
//   OnStage(kSubset, ...)        the subset start: a first pass on a part of the data, whose
//                                own kStart and iterations follow
//   OnStage(kStart, ...)         the rollouts and Jacobians at the initial values (per model)
//   OnIteration(info)            every Ceres iteration (iteration 0: the start), accepted or not
//   OnStepTest(ratio, before, text) the statistical stop's test of an iterate
//   OnStage(kRefit, ...)         auto multiple shooting refits in segments (a second table follows)
//   OnStage(kUncertainty, ...)   the Jacobian at the estimate
//   OnStage(kIntervalCheck, ...) the cost along the intervals
// The runner adds OnWarning (the data's warnings before the fit, a checkpoint that could not be
// written), OnStage(kCheck, ...) for a diagnosis after the fit (sysid/run/initial_state_check.h)
// and, for several starts, OnStartDone per finished start. FitResult::warnings holds the
// fit's own warnings.
// OnProgress comes inside a long rollout or Jacobian column (every tenth of its steps, at most one
// per FitOptions::advanced.progress_seconds), from the simulator's worker threads: it must be
// thread-safe. Every other event comes from the thread that called Fit. `seconds` is the time since
// Fit began.
#pragma once

#include <string>

#include "sysid/types.h"

namespace mjsysid {

// the named stages of a fit that report a line (FitObserver::OnStage)
enum class FitStage {
  kStart,          // rollouts and Jacobians at the initial values
  kRefit,          // auto: the fit starts again in multiple-shooting segments
  kGlobal,         // a pass of the global stage (sysid/fit/global_stage.h)
  kSubset,         // the subset start's pass (sysid/fit/subset_start.h)
  kUncertainty,    // the Jacobian at the estimate
  kIntervalCheck,  // the intervals' quadratic model against the cost
  kCheck,          // a diagnosis: the fit again with one setting changed (sysid/run/)
};

class FitObserver {
 public:
  virtual ~FitObserver() = default;
  // a stage begins; text says what it simulates (e.g. "rollout and Jacobian of 3 sequences")
  virtual void OnStage(FitStage /*stage*/, const std::string& /*text*/, double /*seconds*/) {}
  // one optimiser iteration (as appended to FitResult::trace)
  virtual void OnIteration(const IterationInfo& /*info*/) {}
  // the statistical stop's test (sysid/solve/gn_convergence.h): the predicted Gauss-Newton step in
  // standard errors (largest over the variables; NaN: not tested) and one line saying what was
  // tested or why not. before_jacobian false: of the iterate just reported (with its Jacobian);
  // true: of the next iterate, before its Jacobian (with the previous one), reported before it
  virtual void OnStepTest(double /*step_std_errors*/, bool /*before_jacobian*/,
                          const std::string& /*text*/) {}
  // inside one long rollout or Jacobian column: `what` ("rollout", "Jacobian column"), done of
  // total steps. Called from worker threads.
  virtual void OnProgress(const char* /*what*/, int /*done*/, int /*total*/, double /*seconds*/) {}
  // a warning (the runner's before the fit, e.g. the data's; a checkpoint not written)
  virtual void OnWarning(const std::string& /*text*/) {}
  // a multi-start run (sysid/run/multi_start.h): start k ended (r.error non-empty: it failed),
  // `done` of `total` starts done
  virtual void OnStartDone(int /*k*/, int /*done*/, int /*total*/, const StartResult& /*r*/) {}
};

}  // namespace mjsysid
