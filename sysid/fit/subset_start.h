// The subset start (FitOptions::subset_start, experiment `solver.subset_start`; off by default for
// now, docs/numerics.md "Subset start"): the local fit's first iterations on less data. Before the
// local fit (sysid/fit/policy.cc), a fit pass on the first 1 / kSubsetDivisor of every sequence's
// samples from the user's starts; its estimate is the local fit's start on all the data, whose last
// iterations, statistical stop and covariance are always on everything.
//
// Why: from a start 20-40 % off, a fit spends most of its iterations far from the minimum, each at
// the price of a whole Jacobian of every sequence ((1 + np) rollouts of all the data). Far from
// the minimum a part of the data points the same way as all of it; a rollout of a sequence's first
// samples costs that fraction of the whole, and from the subset's estimate (about sqrt(divisor)
// standard errors of the whole data away) the fit on everything ends in one or two iterations, as
// from an equation-error start. Measured in docs/numerics.md ("Subset start").
//
// The subset: a prefix of every sequence (its first ceil(T / kSubsetDivisor) samples, with its
// logged states and, where the controls share the samples' rows, its controls), so that every
// sequence's own excitation and start are kept and a rollout of the subset simulates 1 / divisor
// of the steps. Every sequence keeps at least kSubsetMinSamples samples.
//
// Runs when: options.subset_start; the fit has parameters and no pending `initial: auto` start
// (the equation-error start is the better start and runs instead); single shooting or auto
// segments (FitOptions::segment_steps <= 0); no estimated initial states; not sharded
// (sysid/mpi/); and the subset is at most half the data (short logs: nothing to save).
//
// Kept when the subset pass solved in single shooting (its auto probe chose no segments and no
// Jacobian warning stopped it), decreased its cost, and left no parameter on a bound it did not
// start on (a parameter the prefix does not determine runs to a bound: the start would be worse
// than the user's). Else the local fit starts from the user's starts as without the stage.
//
// The result: the local fit's, with the subset pass's seconds, simulation steps and ledger rows
// (prefixed "subset start: ") joined before its own (its trace is on other data: not joined), and
// FitResult::subset_start saying what ran and whether its estimate was the start. The parameters'
// `initial` stay the user's starts; the initial cost and signals are the local fit's, at the
// subset's estimate when it was kept. Measurement terms and control delays start at their own
// initial values in both passes.
#pragma once

#include "sysid/solve/fit_state.h"
#include "sysid/types.h"

namespace mjsysid {

// the subset is the first 1 / kSubsetDivisor of every sequence's samples
constexpr int kSubsetDivisor = 8;
// ... and at least this many samples of each sequence
constexpr int kSubsetMinSamples = 50;

// What the subset start did, to be joined into the local fit's result (JoinSubsetStart)
struct SubsetStartRun {
  bool ran = false;   // a subset pass ran (its records below)
  bool kept = false;  // its estimate is the local fit's start (the problem's starts hold it)
  std::vector<double> user_starts;  // the starts before it (physical values, one per parameter)
  FitResult records;                // the subset pass's seconds, steps and ledger
  std::string text;                 // FitResult::subset_start
};

// Runs the subset pass when it applies (see above) and, when kept, sets the problem's parameter
// starts to its estimate. A pass that throws a simulation error or is interrupted is not kept
// (only std::bad_alloc propagates).
SubsetStartRun SubsetStart(const FitParts& parts, const FitOptions& options);

// Joins what the subset start did into the local fit's result: records, the user's starts as
// `initial`, FitResult::subset_start; and puts the user's starts back into the problem (alone
// when result is nullptr: the local fit threw)
void JoinSubsetStart(const FitParts& parts, SubsetStartRun run, FitResult* result);

}  // namespace mjsysid
