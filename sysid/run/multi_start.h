// Multi-start fits (experiment `solver.starts: N`, `sysid fit --starts N`): N fits of one problem
// from starts spread within the bounds, the best kept, the spread of the estimates reported and
// local minima flagged, so that a user learns that the estimate depends on the start before a
// second run on the same data tells them.
//
// Starts (SpreadStarts): start 0 is the experiment's own; starts 1..N-1 a Latin hypercube (one
// point per stratum of each parameter, strata paired by random permutations) in the optimiser's
// variable space: log-uniform for `transform: log`, uniform in p / scale or p otherwise, between
// the bounds. A parameter without finite bounds (on the variable side) is spread over +-50 % of
// its start (+-0.5 when the start is 0), clipped to the bound it has. Deterministic for a seed
// (std::mt19937_64, its raw output: the same numbers on every platform). Fitted measurement
// terms (delay, gain, bias) are not spread: every start has their experiment values.
//
// Runs (FitFromStarts): every start is a complete Problem::Fit of its own Problem (the same models,
// sequences and measurement terms), min(N, threads) of them at a time, the simulator threads
// divided among them. The best start is the lowest final cost among fits with an honest verdict
// (converged or model_mismatch), else the lowest of all; its FitResult is returned, with
// `starts` (every start: start values, estimate, costs, status, iterations), `best_start` and
// `start_spread` (per estimated value: min, max, (max - min) / |best|), `seconds` the wall time of
// all of them and `simulation_steps` their sum. A start whose fit throws (a simulation that fails
// at a spread start) is recorded with its error and cost +inf; when every start fails, the first
// start's error is rethrown.
//
// Local minima: a start k is in another minimum when its final cost exceeds the best by more
// than the noise explains (sysid/assess/chi_square.h, AboveByMoreThanNoise: s^2 the best fit's
// residual variance, p the number of estimated values),
// and at least one estimate differs from the best by more than the best's 95 % half-interval (or
// by more than 1e-3 relative when the best has no finite interval). Then a warning names the
// starts, their fits' verdicts, their costs and the parameters that differ, and those starts'
// status in `starts` is local_minimum.
//
// Interruption: FitOptions::interrupt stops every running fit after its iteration and starts no
// new one (recorded with status interrupted, error "not started (interrupted)"); the best of what
// ran is the result, with status interrupted (intervals not valid) and a warning saying how many
// starts did not finish. Interrupted starts are never counted as local minima.
//
// The result's parameters (their `initial` included) are the best start's.
#pragma once

#include <cstdint>
#include <functional>
#include <memory>
#include <string>
#include <vector>

#include "core/state.h"
#include "sysid/run/fit_experiment.h"
#include "sysid/types.h"

namespace mjsysid::run {

// n x np physical start values (row 0: the parameters' own initial values); n >= 1
RowMatrix SpreadStarts(const std::vector<FitParameter>& parameters, int n, std::uint64_t seed);

// The fits of bp from n starts (n >= 2), options as for one fit (options.threads: all the fits'
// threads together). progress: OnStartDone to options.observer per finished start (from the
// worker threads, one at a time). Throws what a single fit throws when every start fails.
// on_problem (FitRunOptions::on_problem: a fit sharded across MPI ranks, sysid/mpi/): called with
// each start's Problem before its fit; the starts then run one after another, each with all the
// threads.
FitResult FitFromStarts(const BuiltProblem& bp, const FitOptions& options, int n,
                        std::uint64_t seed, bool progress,
                        const std::function<void(Problem&, FitOptions*)>& on_problem = {});

// a Problem of bp's models, measurement terms, control delays and sequences with bp's parameters
// starting at initial (physical values, one per parameter): one start of FitFromStarts
std::unique_ptr<Problem> ProblemFrom(const BuiltProblem& bp, const Eigen::VectorXd& initial);

// the local-minimum warnings of a multi-start result (empty when none): see above
std::vector<std::string> LocalMinimaWarnings(const FitResult& result);
// the starts of a multi-start result in another minimum (see above); FitFromStarts sets their
// StartResult::status to local_minimum after the warning (which names their own verdicts)
std::vector<size_t> StartsInOtherMinima(const FitResult& result);

}  // namespace mjsysid::run
