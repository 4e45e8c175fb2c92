// FitLedger: where the simulated steps and the wall time of one fit go, phase by phase (issue 15:
// the distance of a fit's time per iteration from the simulation floor (1 + np) * sum T * t_step).
//
// A fit moves through phases (the equation-error start, the input checks, the solve's Jacobians
// and trial rollouts, the uncertainty, the interval check, the final signals, ...). Enter(phase)
// charges the steps and seconds since the previous Enter to the previous phase and counts one
// entry of the new one, so the rows always add up to the whole fit: sum of LedgerRow::steps =
// FitResult::simulation_steps, sum of seconds = the fit's wall time up to Finish(). A phase
// entered twice (e.g. the solve's Jacobians once per iteration) accumulates in one row, in the
// order of first entry.
//
// The task model (core/thread_pool.h): a second counter, the steps on the critical path at 2
// workers (the sum of Simulator::ParallelLoad().span[2]), is charged the same way to
// LedgerRow::critical_steps, so that steps / critical_steps is a phase's (and the fit's) modelled
// 2-thread speed-up, exact and independent of the machine's load.
//
// The time inside the simulators' batches (core/thread_pool.h, PoolTime; MeasureBatches) is charged
// the same way to LedgerRow::batch_seconds, batches, wake_seconds, wait_seconds and
// batch_cpu_seconds (the fit thread's CPU time in them): a phase's seconds - batch_seconds is its
// serial time, which a second thread does not shorten.
//
// Steps come from a counter the caller supplies (the sum of Simulator::StepCount over the fit's
// simulators, which may not exist yet when the ledger starts: then it returns 0); it grows, except
// that a reading below the last one means the counter restarted from 0 (PrepareFit builds
// new simulators when a Problem is fitted again: a refit, another start). Time is
// std::chrono::steady_clock. Not thread-safe: the fit's own thread only (as the evaluation cache,
// sysid/solve/evaluation_cache.h).
#pragma once

#include <chrono>
#include <functional>
#include <iterator>
#include <string>
#include <vector>

#include "core/thread_pool.h"
#include "sysid/types.h"

namespace mjsysid {

// The phases of Problem::Fit, in the order a fit meets them (one definition for the fit, the
// evaluation callback and the benchmark). Unscoped, so that the fit's stages name them kPhaseX.
enum FitPhase {
  kPhaseAutoStart,
  kPhasePrepare,
  kPhaseSetup,
  kPhaseJacobians,
  kPhaseTrials,
  kPhaseSolver,
  // the compressed blocks' rows and folds made ahead on the simulator's workers after a Jacobian
  // batch (sysid/solve/compressed_cost.h, "Folds ahead"; a batch: not serial)
  kPhaseFolds,
  // of the trial rollouts' steps, the Jacobian columns computed ahead of points Ceres then did not
  // take (sysid/solve/evaluation_cache.h, "Columns ahead"; more than one thread only)
  kPhaseAheadUnused,
  kPhaseEstimate,
  kPhaseCovariance,
  kPhaseIntervalCheck,
  kPhaseSignals,
};

// the name of a phase's ledger row (LedgerRow::phase), as FormatLedger prints it
constexpr const char* FitPhaseName(FitPhase phase) {
  // in the order of FitPhase
  constexpr const char* kNames[] = {
      "equation-error start (initial: auto)",
      "input checks: initial rollouts + Jacobians",
      "setup: Ceres problem",
      "solve: Jacobians",
      "solve: trial rollouts (steps, line search)",
      "solve: residuals, Ceres linear algebra",
      "solve: folds ahead (rows + thin QR)",
      "solve: columns ahead, not used",
      "uncertainty: evaluation at the estimate",
      "uncertainty: covariance",
      "interval check (cost at +-1 std)",
      "final signals, derived, status",
  };
  static_assert(std::size(kNames) == kPhaseSignals + 1, "a name per phase");
  return kNames[phase];
}

class FitLedger {
 public:
  // steps: the total step count of the fit so far (non-decreasing)
  explicit FitLedger(std::function<long long()> steps);
  // critical: steps on the critical path at 2 workers (see above), restarting with steps
  FitLedger(std::function<long long()> steps, std::function<long long()> critical);

  // time: the summed PoolTime of the fit's simulators (restarting with steps); none: the batch
  // columns stay 0
  void MeasureBatches(std::function<PoolTime()> time);

  // charges what happened since the last Enter to the phase then current; phase becomes current
  void Enter(const std::string& phase);
  void Enter(FitPhase phase) { Enter(FitPhaseName(phase)); }
  // the phase entered last ("" before the first Enter)
  const std::string& current() const { return current_; }
  // moves steps (not their critical steps: the batch's makespan stays where it ran) from row
  // `from` to row `to` (added, 1 entry, when new); nothing when from has no row or steps <= 0
  void Move(FitPhase from, FitPhase to, long long steps);
  // charges the current phase and returns every row (order of first entry)
  std::vector<LedgerRow> Finish();

  // Inside the solve the evaluation callback enters "solve: Jacobians" or "solve: trial rollouts"
  // and, after simulating, "solve: residuals, Ceres"; outside the solve (the evaluation at the
  // estimate, the interval check) the evaluations belong to the phase the caller entered.
  bool solving = false;

 private:
  void Charge();

  std::function<long long()> steps_;
  std::function<long long()> critical_;  // may be empty: critical_steps stay 0
  std::vector<LedgerRow> rows_;
  std::string current_;
  long long last_steps_ = 0;
  long long last_critical_ = 0;
  std::function<PoolTime()> time_;  // may be empty
  PoolTime last_pool_;
  std::chrono::steady_clock::time_point last_time_;
};

// The ledger as a table, one line per phase: entries, steps, steps / (sum T) ("rollouts"), seconds
// and share of the time, and the modelled 2-thread speed-up steps / critical_steps ("2w model",
// "-" for a phase without steps), and the seconds outside the simulators' batches ("serial s");
// sum_t: the fit's simulated samples per rollout of every sequence
std::string FormatLedger(const std::vector<LedgerRow>& rows, long long sum_t);

}  // namespace mjsysid
