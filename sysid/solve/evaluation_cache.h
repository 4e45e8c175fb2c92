// The evaluation cache of a fit: per segment, the core's rollout and, once asked for, its
// Jacobians at the variable values last evaluated, so that no rollout is computed twice.
//
// What is cached. One Entry per Segment (a sequence, or in multiple shooting a piece of one),
// keyed by the values it was simulated at: key = [z (np: the optimiser's parameter variables, the
// whole vector, absent when the fit has none), x_0 (nphys: the segment's initial physics vector
// [qpos, qvel, act]), with grids the delays (nu, s) its sequence's controls were held with
// (SampleGrid::delay; a fitted control delay changes them, SolveContext::SyncControlDelays)]. An
// Entry holds the Trajectory (core/simulator.h: T + 1 states, T sensor rows, row-major) and, once
// asked for, its Sensitivity: ncol = the model's simulator parameters (ParameterSet order, physical
// units) followed, when the segment's x_0 is a variable (Segment::block >= 0), by its nx tangent
// directions; DyDp is T*ns x ncol, DxDp ((T+1)*nx x ncol, tangent space) is filled only for
// segments with a continuity residual (Segment::next >= 0) or fitted states (Segment::state_rows).
//
// Reuse. Ceres evaluates the residuals at a trial point and, when it accepts the step, the
// Jacobians at the same point: the rollout is reused and only the Jacobians are added. The
// entry with Jacobians that a trial point replaces is kept aside until the next Jacobians, so
// that the evaluation at the estimate after the solve (the last iterate, whose Jacobians the LM
// computed) simulates nothing. Before
// each evaluation Prefetch() (Ceres' EvaluationCallback, sysid/solve/cost_functions.h) simulates
// every segment of a model whose key changed in one batch, so the simulator runs the segments (and
// their Jacobian columns) in parallel instead of one after another; Evaluate() then finds them.
//
// Columns ahead (more than one thread, directional Jacobians). A batch of n rollouts on W workers
// leaves ceil(n / W) W - n worker slots idle for a rollout's time (3 sequences on 2 workers: one);
// the rollouts of a trial point fill them with the first Jacobian columns of the point, each
// following its rollout step by step (Simulator::RolloutWithColumnsAhead), so that when Ceres
// accepts the point and asks for its Jacobians only the rest is computed (a batch of 3 x 3
// columns on 2 workers: 8 tasks, 4 rounds instead of 5). Speculative: a rejected point's columns
// are work for nothing (AheadStepsUnused), but on the idle workers, so they cost CPU time, not
// wall time (by the pool's task model, core/thread_pool.h). Results are the same bit for bit.
// Where columns ahead would save no round of the Jacobians (3 sequences of 2 columns on 2
// workers: 5 columns take as many rounds as 6), the trial's rollouts run in pieces instead
// (Simulator::Rollout), which fill the idle slots themselves: 1.5 rollout times instead of 2.
//
// Failure. A rollout or Jacobian that throws (SimulationError: a MuJoCo warning or a non-finite
// value; MujocoError) is caught: the Entry records failed (or jacobians_failed) with the message,
// so that the cost function rejects the trial point (the trust region shrinks) instead of the fit
// ending. Arguments are not checked: they come from PrepareFit.
//
// Threads: single-threaded, enforced. Every call must come from the thread that constructed the
// cache; a call from any other thread is a broken invariant and aborts with a message. Problem
// runs Ceres with num_threads = 1 (the simulators are parallel inside), so Ceres calls the cost
// functions and the EvaluationCallback on the thread that called Fit or CheckJacobians, which is
// the one whose Prepare built the cache. Not a mutex: Evaluate returns a reference into the cache,
// which the caller reads after the call, and the simulators (one per model, shared by its
// segments) are not reentrant either, so parallel evaluation would only wait.
//
// Ownership: borrows the simulators, the fit parameters, the sequences and the segments; they
// must outlive the cache and stay unchanged while it is used, except the simulators' parameter
// values, which the cache writes (ApplyVariables).
#pragma once

#include <string>
#include <thread>
#include <vector>

#include "core/simulator.h"
#include "sysid/data/sample_grid.h"
#include "sysid/types.h"

namespace mjsysid {

// a piece of one sequence simulated from its own initial state (the whole sequence in single
// shooting)
struct Segment {
  int seq = 0;        // index of its sequence
  int model = 0;      // index of the sequence's model
  int k0 = 0, T = 0;  // first sample and number of samples
  int block = -1;     // state block of x_0 (a variable), or -1: x_0 is the sequence's given x0
  int next = -1;      // state block of the next segment's x_0 (continuity), or -1
  bool state_rows = false;  // fits logged states (sysid/solve/state_residuals.h): needs DxDp too
};

// Writes the physical values of the variables z (one per FitParameter) into the simulator's
// parameters; variables[j] is the index in z of the simulator's parameter j. Only when they
// changed (SetParameters may run mj_setConst).
void ApplyVariables(const std::vector<FitParameter>& parameters, const std::vector<int>& variables,
                    const double* z, Simulator* sim);

class EvaluationCache {
 public:
  // the simulator of one model and where its parameters sit among the variables z
  struct Model {
    Simulator* sim = nullptr;    // borrowed
    std::vector<int> variables;  // index in z of each simulator parameter (ParameterSet order)
  };

  struct Entry {
    std::vector<double> key;  // z (when given), then x_0 of the segment
    bool failed = false;      // the rollout at key failed: tr is not valid
    bool has_jacobians = false;
    bool jacobians_failed = false;
    std::string error;  // why the rollout or the Jacobians failed
    Trajectory tr;
    Sensitivity s;       // valid when has_jacobians
    ColumnsAhead ahead;  // Jacobian columns computed with the rollout (see Columns ahead)
  };

  // parameters: the fit's (z has one variable per entry); sequences: their ctrl rows are the
  // segments' inputs; segments: Segment::model indexes models; jacobian: the core options,
  // initial_state and state_jacobians set per segment as above
  EvaluationCache(std::vector<Model> models, const std::vector<FitParameter>* parameters,
                  const std::vector<FitSequence>* sequences, const std::vector<Segment>* segments,
                  const JacobianOptions& jacobian);
  // the same with the sequences' simulation grids (sysid/data/sample_grid.h; one per sequence,
  // borrowed): a segment's input is SimulatedSteps rows of its grid's ctrl from k0, so that its
  // Trajectory::T may exceed Segment::T by one
  EvaluationCache(std::vector<Model> models, const std::vector<FitParameter>* parameters,
                  const std::vector<FitSequence>* sequences, const std::vector<Segment>* segments,
                  const JacobianOptions& jacobian, const std::vector<SampleGrid>* grids);

  // The entry of a segment at variables z (nullptr when the fit has no parameters) and initial
  // physics vector x0 (nphys), with its Jacobians if asked for: from the cache, else simulated
  // alone. Valid until the next call of Evaluate, Prefetch or Seed.
  const Entry& Evaluate(int segment, const double* z, const double* x0, bool jacobians);
  // The entry Evaluate would return at these arguments without simulating, when its rollout (and,
  // when asked for, its Jacobians) succeeded; else nullptr. Simulates nothing; valid as Evaluate's.
  const Entry* Ready(int segment, const double* z, const double* x0, bool jacobians) const;

  // Brings every segment to z and x0[segment] (with Jacobians if asked for), batched per model:
  // one Rollout call for the segments whose key changed, one Jacobians call per kind of segment.
  // A nullptr x0[segment] leaves that segment out (a distributed worker's share, sysid/mpi/).
  void Prefetch(const double* z, const std::vector<const double*>& x0, bool jacobians);

  // Stores a rollout computed elsewhere at z and x0 (PrepareFit's rollouts at the initial
  // values) with its Jacobians when s holds every parameter column (segments without x_0 columns).
  // DxDp is dropped unless the segment reads it (continuity or fitted states).
  void Seed(int segment, const double* z, const double* x0, Trajectory tr, Sensitivity s);

  // the entry of a segment as last evaluated, without simulating (an empty key: none, or
  // cancelled); e.g. the rollouts at the estimate after its evaluation
  const Entry& Cached(int segment) const { return entries_[segment]; }

  // the segment's previous iterate: the entry with Jacobians that the current entry's trial
  // point replaced (kept aside, see Reuse), or nullptr. Read as the Jacobian at its own point
  // (its key), for the statistical stop before the last Jacobian (sysid/solve/gn_convergence.h);
  // the current entry is never given its Jacobians.
  const Entry* Previous(int segment) const {
    const Entry& kept = kept_[segment];
    return kept.key.empty() || !kept.has_jacobians ? nullptr : &kept;
  }

  // Rollouts at several points z (x0 per segment as for Prefetch; every segment with an x0) in one
  // batch per model (Simulator::RolloutAt), held aside until Evaluate or Prefetch asks for one of
  // them, which then costs no simulation; replaces the points held before. For points known
  // together (the interval check's +- one standard error of a variable: 2 n rollout tasks in one
  // batch instead of two batches of n). A failed batch holds nothing (the points are simulated
  // when asked, failing there as before).
  void PrefetchPoints(const std::vector<const double*>& zs, const std::vector<const double*>& x0);

  // whether trial points get columns ahead (see Columns ahead; off by default): on in the solve,
  // where trial points are followed by their Jacobians when accepted, off outside it (the
  // interval check's points never are)
  void SetColumnsAhead(bool on) { columns_ahead_ = on; }
  // step calls of the columns computed ahead (see Columns ahead) that no Jacobian has taken (yet)
  long long AheadStepsUnused() const { return ahead_steps_ - ahead_used_steps_; }

 private:
  // aborts unless called on the constructing thread (see Threads above)
  void CheckThread(const char* where) const;
  std::vector<double> KeyOf(int segment, const double* z, const double* x0) const;
  SequenceInput InputOf(int segment, const double* x0) const;
  JacobianOptions GroupOptions(int segment) const;
  std::vector<int> AheadColumns(int mo, const std::vector<int>& segs) const;
  // the entries of segs (all of model mo) at z and x0s: rollouts of those whose key changed in one
  // batch, then the missing Jacobians batched by the columns and rows they need
  void Simulate(int mo, const std::vector<int>& segs, const double* z,
                const std::vector<const double*>& x0s, bool jacobians);

  std::vector<Model> models_;
  const std::vector<FitParameter>* parameters_;  // borrowed, as the three below
  const std::vector<FitSequence>* sequences_;
  const std::vector<Segment>* segments_;
  const std::vector<SampleGrid>* grids_ = nullptr;  // borrowed; nullptr: sequences' ctrl
  JacobianOptions jacobian_;
  std::vector<Entry> entries_;  // one per segment
  // per segment: the entry with Jacobians that a trial point replaced in entries_ (empty key:
  // none), given back without simulation when its point is asked for again; dropped when the
  // segment's next Jacobians are computed, so one Jacobian per segment is held
  std::vector<Entry> kept_;
  // per segment: the entries PrefetchPoints simulated, taken (moved out) when asked for
  std::vector<std::vector<Entry>> spare_;
  std::thread::id owner_;                             // the constructing thread
  long long ahead_steps_ = 0, ahead_used_steps_ = 0;  // see AheadStepsUnused
  bool columns_ahead_ = false;                        // SetColumnsAhead
};

}  // namespace mjsysid
