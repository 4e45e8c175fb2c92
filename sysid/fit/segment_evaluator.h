// The segment residuals of a prepared fit, evaluated outside its Ceres problem: what a shard of a
// sharded fit (sysid/mpi/) sees of the fit state (sysid/solve/fit_state.h), and all it may change:
// the variables it is given, the free states it solves, and the rejections and Jacobian warnings
// it notes.
//
// Shapes: np parameters (z), nm measurement terms and control delays (m); segments in sequence
// order, each with its sequence, its state block (-1: none) and the next segment's (-1: none)
// (Segment, sysid/solve/evaluation_cache.h). Cost functions: SegmentCost and StateCost
// (sysid/solve/cost_functions.h, state_residuals.h), on the parameter blocks z, m (sensor costs
// only), the segment's x_0 and the next x_0 (sensor costs only), each present when the fit has it.
//
// Threads: as the fit state, one thread; the simulators are parallel inside Prefetch.
#pragma once

#include <ceres/ceres.h>

#include <functional>
#include <memory>
#include <string>
#include <vector>

#include "core/state.h"
#include "sysid/solve/evaluation_cache.h"  // Segment
#include "sysid/solve/state_blocks.h"
#include "sysid/types.h"

namespace mjsysid {

// sysid/solve/fit_state.h
struct FitParts;
struct PreparedFit;
struct FitVariables;
struct FitDiagnostics;
struct SolveContext;
class Problem;
class StateManifold;

class SegmentEvaluator {
 public:
  // parts: a prepared fit's (borrowed; they must outlive the evaluator)
  explicit SegmentEvaluator(const FitParts& parts);

  // the variables: z (np values) and m (nm); SetVariables copies np + nm values (z, then m)
  int np() const;
  int nm() const;
  const std::vector<double>& z() const;
  const std::vector<double>& m() const;
  void SetVariables(const double* values);

  // the data: sequences, their segments (in sequence order) and each segment's model
  int num_sequences() const;
  int num_segments() const;
  const Segment& segment(int s) const;
  const std::string& sequence_name(int q) const;
  const StateDims& dims(int s) const;
  const StateManifold& manifold(int s) const;
  // the work of sequence q's rollout with Jacobians (PreparedFit::SequenceWork), for sharing the
  // sequences out
  double SequenceWork(int q) const;
  // whether some segment starts from a free state (multiple shooting, estimated initial states)
  bool free_states() const;
  // the free states, one block per segment with block >= 0 (physics vectors [qpos, qvel, act]),
  // and the x_0 of a segment at them (its block, or its sequence's given x0)
  StateBlocks& states();
  const StateBlocks& states() const;
  const double* X0(int s) const;

  // the segments whose x_0 is not null in x0 (one pointer per segment) simulated at the current
  // z, in the simulators' batches, Jacobians when asked (EvaluationCache::Prefetch)
  void Prefetch(const std::vector<const double*>& x0, bool jacobians);
  // segment s's cost functions: sensors and continuity; fitted states (nullptr: none)
  std::unique_ptr<ceres::CostFunction> SensorCost(int s) const;
  std::unique_ptr<ceres::CostFunction> StateCost(int s) const;

  // the first Jacobian warning of segment s (nullptr: none)
  const std::string* JacobianWarning(int s) const;
  void NoteRejection(const std::string& what);
  void NoteJacobianWarning(int s, const std::string& what);
  // the rejections so far (count and first message), to restore after trial points that are not
  // Ceres' (a shard's own inner search)
  struct Rejections {
    int count = 0;
    std::string first;
  };
  Rejections rejections() const;
  void RestoreRejections(const Rejections& r);

  // the preparation's facts every shard agrees on: per parameter whether it moves this shard's
  // data (PreparedFit::moves), the check of the moves combined over the shards (throws
  // ParameterError like CheckParametersMove), the parameters' physical start values and the
  // segment length as prepared (FitOptions::segment_steps)
  const std::vector<bool>& moves() const;
  void CheckMoves(const std::vector<bool>& all) const;
  std::vector<double> InitialValues() const;
  int segment_steps() const;

 private:
  FitParts Parts() const;
  PreparedFit* fit_;
  FitVariables* vars_;
  FitDiagnostics* diag_;
  SolveContext* solve_;
};

// The entry points of a shard (sysid/mpi/; defined in sysid/problem.cc).

// Validates and prepares the fit as Problem::Fit does, without solving: for a worker that
// evaluates a share of the segments (sysid/mpi/). Returns the view of problem's fit state a
// shard has (valid while problem lives). Throws like Fit on bad input.
SegmentEvaluator PrepareOnly(Problem* problem, const FitOptions& options);

// A sharded start (sysid/mpi/): PrepareFit rolls out and differentiates at the initial values
// only the sequences owned(work) marks (work: per sequence, SequenceWork; the result: one bool
// per sequence, empty: all), and does not itself check that every parameter moves the data: it
// leaves moves() (per parameter: some owned sequence sees it) for the caller to combine over all
// shards and check (CheckMoves). The fit rolls out the other sequences at the initial values for
// the result only (rollouts, no Jacobians). With free states (multiple shooting, estimated initial
// states) PrepareFit rolls out the other sequences too (no Jacobians), so that every shard starts
// every segment state as one process does.
void ShardStart(Problem* problem,
                std::function<std::vector<bool>(const std::vector<double>& work)> owned);

}  // namespace mjsysid
