// `mpirun -n N sysid fit EXP.yaml`: a fit whose sequences are sharded across MPI ranks.
//
// Roles. Every rank reads and validates the experiment and its logs (run::BuildProblem) and
// prepares the fit (PrepareOnly, sysid/fit/prepare.h) with a sharded start (ShardStart): the
// initial rollouts and Jacobians of its own sequences only, so the start costs one whole-data
// Jacobian spread over the ranks, not one per rank. Then all ranks agree that every one of them is
// ready (AgreeReady) before any evaluation, so bad input on any rank (a log it cannot read) ends
// the run on every rank before the fit, with that rank's message naming it and its host; and they
// combine the checks that need every sequence (AgreeMoves: a parameter without effect on all the
// data), which then fail on every rank with the same message. Rank 0 runs Ceres through the
// ordinary Problem::Fit with a ShardedResiduals (sysid/problem.h's ResidualShards): one residual
// block for all segments. The other ranks loop in ServeFit.
//
// One evaluation (ShardedResiduals::PrepareForEvaluation, Ceres' EvaluationCallback): rank 0
// broadcasts [command, jacobians?, z (np), m (nm)] (n = np + nm values after the header); every
// rank simulates its contiguous range of segments (its simulator threads in parallel,
// EvaluationCache::Prefetch of its share), compresses each segment (residuals only: its sum r^2;
// Jacobians: the (n + 1) x (n + 1) thin-QR block of sysid/mpi/shards.h) and reduces them to the
// maximal nodes of the fixed tree over the segments inside its range (at most 2 log2(range)
// nodes), which rank 0 gathers (MPI_Gatherv) and reduces to the root: one Ceres residual block of
// n + 1 rows with the exact cost, gradient and Gauss-Newton matrix of all the residuals. Rank 0's
// memory and traffic per evaluation are O(ranks x log(S / ranks) x n^2), independent of the
// number of samples; it never holds the Jacobian of another rank's segments. The tree makes the
// root bitwise the same for any rank and thread count, hence the same estimates and iterations.
//
// Free states (multiple shooting with fixed segment_steps, estimated initial states): the leaves
// of the tree are whole sequences instead of segments, each owned by one rank with all its
// segments and continuity residuals; the owner solves the sequence's states at every broadcast
// point and eliminates them (sysid/mpi/state_projection.h: variable projection), so rank 0's
// Ceres sees z and m only and gets the same (n + 1)^2 blocks. The solved states stay on their
// rank (the warm start of the next points); rank 0 collects them once after the fit
// (CollectStates: command kStates, MPI_Gatherv in rank order) for the result.
//
// `segment_steps: auto` (sysid/solve/multiple_shooting.h): every rank rolls out and probes every
// sequence at the initial values in Prepare (one nominal and one probe rollout of each, no
// Jacobians), so every rank chooses the segments one process chooses, without a collective call
// before the ranks agree that they are ready. Its refits in segments (the single-shooting
// Jacobian warned, or the fit did not converge) are Problem::Fit calling itself on rank 0: the
// second AddResidualBlocks broadcasts kPrepare with the new segment length and every worker
// prepares again (ServeFit). A worker's Jacobian warning reaches rank 0 with the step it names,
// so the refit's segments are those of one process.
//
// Several starts (--starts, sysid/run/multi_start.h) run one after another, each a Problem of
// its own on rank 0 (NextProblem before its DistributeResiduals): from the second on,
// AddResidualBlocks broadcasts kStart with its physical start values, every worker builds the
// same Problem (run::ProblemFrom) and prepares it, and the ranks agree on readiness and on the
// parameters' effect again (a failure fails that start only).
//
// Stop signals: see ServeFit and SetInterrupt (the fit ends after the current iteration).
//
// Faults. A rank that dies (killed, crashed) ends the job through the MPI runtime (mpirun names
// the rank, its PID and host); rank 0's checkpoint after every successful iteration is written
// atomically (sysid/run), so the last complete one stays on disk for `sysid fit --resume`. A
// simulation that fails at a trial point on any rank rejects that point (the trust region
// shrinks), as in a fit on one machine.
//
// Threads: MPI is called from the thread that called MPI_Init only (MPI_THREAD_FUNNELED): Ceres
// runs with one thread and calls the EvaluationCallback there.
#pragma once

#include <ceres/ceres.h>

#include <atomic>
#include <memory>
#include <optional>
#include <stdexcept>
#include <string>
#include <vector>

#include "sysid/fit/segment_evaluator.h"
#include "sysid/io/experiment.h"
#include "sysid/mpi/shards.h"
#include "sysid/problem.h"

namespace mjsysid::mpi {

// Initialises MPI (MPI_THREAD_FUNNELED) when the process was started by an MPI launcher (mpirun,
// mpiexec, srun: OMPI_COMM_WORLD_SIZE, PMI_SIZE or PMIX_RANK set), else leaves it alone so that a
// plain `sysid` run does not start an MPI runtime. Idempotent. Finalize ends it (once; safe when
// never initialised).
void Initialize(int* argc, char*** argv);
void Finalize();
bool Active();  // Initialize started MPI (the process runs under a launcher) and not finalised
int Rank();     // 0 without MPI
int Size();     // 1 without MPI
// "rank R on HOST"
std::string RankName(int rank);

// Bad input for a sharded fit: a rank that was not ready (the message names the rank and its
// host)
class RankError : public std::invalid_argument {
 public:
  using std::invalid_argument::invalid_argument;
};

// every rank once, before the first evaluation: true when every rank is ready (ok); else false and
// *failure = the message of the lowest failing rank, prefixed with RankName
bool AgreeReady(bool ok, const std::string& message, std::string* failure);

// every rank, once, after AgreeReady succeeded: combines the parameters' moves (SegmentEvaluator::
// moves) over the ranks (a parameter moves the data when it moves the sequences of some rank: a
// logical or) and throws ParameterError, the same on every rank, for a parameter that moves none
void AgreeMoves(const SegmentEvaluator& segments);
// the contiguous sequence ranges of the ranks (ShardRanges: ranks + 1 entries), by each
// sequence's work (simulation steps x Jacobian columns, SegmentEvaluator::SequenceWork); a sharded
// start's ShardStart calls it with the work before the initial rollouts
std::vector<int> SequenceRanges(const std::vector<double>& work, int ranks);
std::vector<int> SequenceRanges(const SegmentEvaluator& segments, int ranks);
// the sequences of `rank` (SequenceRanges), one bool per sequence
std::vector<bool> OwnedSequences(const std::vector<double>& work, int rank, int ranks);
// the contiguous segment ranges of a prepared fit's ranks: the segments of SequenceRanges' whole
// sequences (ranks + 1 entries)
std::vector<int> SegmentRanges(const SegmentEvaluator& segments, int ranks);
// The leaves of the tree: whole sequences when the fit has free states (multiple shooting,
// estimated initial states; each sequence's states eliminated on its rank, state_projection.h),
// else segments (single shooting: one per sequence). LeafRanges: their ranges per rank.
int Leaves(const SegmentEvaluator& segments);
std::vector<int> LeafRanges(const SegmentEvaluator& segments, int ranks);

struct Share;  // the buffers of one rank's evaluation (distributed_fit.cc)

// traffic and time of the evaluations so far, as seen by rank 0
struct ShardStats {
  long long evaluations = 0, jacobian_evaluations = 0;
  long long bytes = 0;           // sent and received by rank 0 (broadcast x (ranks - 1) + gather)
  double seconds_mpi = 0;        // rank 0 inside MPI_Bcast / MPI_Gather (includes waiting)
  double seconds_own_share = 0;  // rank 0 simulating and compressing its own share
};

// rank 0: the residual blocks of every rank (see above)
class ShardedResiduals : public ResidualShards, public ceres::EvaluationCallback {
 public:
  ShardedResiduals();
  ~ShardedResiduals() override;

  // ResidualShards: agrees with the other ranks that every one is ready (throws RankError when one
  // is not), then adds the one block of every segment
  void AddResidualBlocks(const SegmentEvaluator& segments, ceres::Problem* problem,
                         const std::vector<double*>& blocks) override;
  ceres::EvaluationCallback* Callback() override { return this; }
  long long NumResiduals() const override { return rows_; }
  int EliminatedColumns() const override { return eliminated_; }
  // rank 0's states of every sequence from their owners (the last Jacobian evaluation's)
  void CollectStates(SegmentEvaluator& segments) override;
  // rank 0's share of the start (OwnedSequences)
  std::vector<bool> OwnedSequences(const std::vector<double>& work) const override;
  // EvaluationCallback: every rank at the current values
  void PrepareForEvaluation(bool evaluate_jacobians, bool new_evaluation_point) override;

  // after the fit: the workers leave ServeFit. Abandon instead when the fit never started
  // (rank 0 failed before AddResidualBlocks): the workers learn the failure and leave. Each at
  // most once, in any order; the second call does nothing.
  void Finish();
  void Abandon(const std::string& message);
  // the fit's interrupt flag (FitOptions::interrupt's), set when a worker reports a stop signal
  // at an evaluation (ServeFit catches SIGINT, SIGTERM and SIGHUP): every rank then stops after
  // the current iteration and rank 0 writes the result of the last good iterate once
  void SetInterrupt(std::atomic<bool>* flag) { interrupt_ = flag; }
  // the next Problem is a new one (FitRunOptions::on_problem, before its DistributeResiduals):
  // from the second on (--starts), its AddResidualBlocks makes the workers build and prepare it
  // at its start values; without this call a second AddResidualBlocks is a refit of the same
  // Problem (auto's segments)
  void NextProblem() {
    new_problem_ = true;
    ++problems_;
  }
  const ShardStats& stats() const { return stats_; }

  // the root of the last evaluation (the residual block's values)
  struct Root {
    bool ok = false;  // every rank evaluated its share
    bool jacobians = false;
    double sum_squares = 0;  // residuals only
    Eigen::MatrixXd r_aug;   // (n + 1) x (n + 1) with Jacobians
  };
  const Root& root() const { return root_; }
  int n() const { return n_; }

 private:
  // the segments of the current Problem (AddResidualBlocks)
  std::optional<SegmentEvaluator> segments_;
  int n_ = 0;
  long long rows_ = 0;
  int eliminated_ = 0;  // tangent columns of the free states
  bool agreed_ = false, done_ = false, new_problem_ = false;
  int problems_ = 0;
  Root root_;
  std::vector<int> ranges_, counts_, displs_, heads_;
  std::atomic<bool>* interrupt_ = nullptr;
  std::vector<double> command_, send_, receive_;
  std::unique_ptr<Share> share_;
  ShardStats stats_;
};

// a worker rank (rank > 0): builds the problem of config (nullptr: this rank already failed with
// `failure`), agrees on readiness, then evaluates its share of the segments until rank 0
// finishes. Catches SIGINT, SIGTERM and SIGHUP (mpirun forwards its own to every rank) and reports
// them with its next evaluation, so that the fit stops after the current iteration (a second
// signal ends the rank at once). Returns the process exit code: 0 (rank 0 reports every failure).
int ServeFit(const io::ExperimentConfig* config, int threads, const std::string& failure);

}  // namespace mjsysid::mpi
