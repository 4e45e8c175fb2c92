// A fit sharded across MPI ranks (sysid/mpi/distributed_fit.h): the session, the agreement before
// the fit, rank 0's residual blocks and the workers' loop.
#include "sysid/mpi/distributed_fit.h"

#include <mpi.h>

#include <array>
#include <chrono>
#include <cmath>
#include <csignal>
#include <cstdio>
#include <cstdlib>
#include <map>
#include <optional>

#include "core/invariant.h"
#include "sysid/mpi/state_projection.h"
#include "sysid/run/fit_experiment.h"
#include "sysid/run/multi_start.h"
#include "sysid/solve/compressed_cost.h"
#include "sysid/solve/multiple_shooting.h"

namespace mjsysid::mpi {
namespace {

// commands (first double of the broadcast): evaluate, finish, send the solved states to rank 0,
// prepare again with the segment length of the second value (auto's refit in multiple shooting)
// or a new Problem at the start values that follow (the next start of --starts)
constexpr double kEvaluate = 1, kFinish = 0, kStates = 2, kPrepare = 3, kStart = 4;
// a rank's reply to an evaluation: [ok, warned segment (-1: none), the step its warning names
// (-1: none), number of nodes], then the nodes
constexpr int kReplyHeader = 4;
constexpr int kHeader = 2;  // doubles before the values

bool g_initialized = false, g_finalized = false;

// A worker's stop signals (SIGINT, SIGTERM, SIGHUP; mpirun forwards its own to every rank): noted
// and reported to rank 0 with the next evaluation; a second one has the default action
constexpr int kStopSignals[] = {SIGINT, SIGTERM, SIGHUP};
volatile std::sig_atomic_t g_stop = 0;
void OnWorkerStop(int) {
  g_stop = 1;
  for (int s : kStopSignals) std::signal(s, SIG_DFL);
}

double Seconds(std::chrono::steady_clock::time_point since) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - since).count();
}

}  // namespace

// the buffers of one rank's evaluation, reused
struct Share {
  // per owned segment: its sensor cost (all blocks) and fitted-state cost (z only; or nullptr),
  // built at the first evaluation
  std::vector<std::array<std::unique_ptr<ceres::CostFunction>, 2>> costs;
  CompressedBlock block;
  std::vector<Eigen::MatrixXd> blocks;  // per owned segment, with Jacobians
  std::vector<double> sums;             // per owned segment: sum r^2
  RowMatrix J, Jz, Jm;
  Eigen::VectorXd r;
  // the fit has free states: the leaves are whole sequences, their states eliminated here
  std::unique_ptr<StateProjection> projection;
};

namespace {

// out = the reply header (kReplyHeader) and, when ok, the maximal tree nodes inside the leaves
// [first, last) of a tree over [0, leaves), each reduced from share's leaf values
void Reply(const SegmentEvaluator& segments, bool ok, int warned, int first, int last, int leaves,
           bool jacobians, const Share& share, std::vector<double>* out) {
  const int step = warned >= 0 ? WarningStep(*segments.JacobianWarning(warned)) : -1;
  out->assign({ok ? 1.0 : 0.0, static_cast<double>(warned), static_cast<double>(step), 0.0});
  if (!ok) return;
  const std::vector<std::pair<int, int>> nodes = CanonicalNodes(first, last, leaves);
  (*out)[3] = static_cast<double>(nodes.size());
  for (const auto& [lo, hi] : nodes) {
    out->push_back(lo);
    out->push_back(hi);
    if (jacobians) {
      const Eigen::MatrixXd R = ReduceTree<Eigen::MatrixXd>(
          lo, hi, [&](int a, int b) { return b - a == 1 ? &share.blocks[a - first] : nullptr; },
          MergeBlocks);
      out->insert(out->end(), R.data(), R.data() + R.size());
    } else {
      out->push_back(ReduceTree<double>(
          lo, hi, [&](int a, int b) { return b - a == 1 ? &share.sums[a - first] : nullptr; },
          [](double a, double b) { return a + b; }));
    }
  }
}

// EvaluateShare (below) with free states (SegmentEvaluator::free_states): the leaves [first, last)
// are whole sequences, each solved for its states and reduced by StateProjection
void EvaluateSequences(const SegmentEvaluator& segments, int first, int last, bool jacobians,
                       Share* share, std::vector<double>* out) {
  if (!share->projection) share->projection = std::make_unique<StateProjection>(segments);
  const int leaves = segments.num_sequences();
  share->sums.assign(std::max(last - first, 0), 0.0);
  share->blocks.resize(std::max(last - first, 0));
  bool ok = true;
  int warned = -1;
  for (int q = first; q < last && ok; ++q) {
    ok = share->projection->Solve(q, jacobians, &share->blocks[q - first], &share->sums[q - first]);
    for (int s = 0; s < segments.num_segments() && warned < 0; ++s) {
      if (segments.segment(s).seq == q && segments.JacobianWarning(s)) warned = s;
    }
  }
  Reply(segments, ok, warned, first, last, leaves, jacobians, *share, out);
}

// One rank's share at the variables (z, m): its segments [first, last) simulated
// (batched), their sensor and state residuals evaluated and, with Jacobians, compressed one
// segment at a time; then the values of the maximal tree nodes of its range (shards.h). out:
// [ok, warned segment (-1: none), number of nodes, then per node: lo, hi and its value (sum r^2,
// or R_aug column-major with Jacobians)].
void EvaluateShare(SegmentEvaluator& segments, int first, int last, bool jacobians, Share* share,
                   std::vector<double>* out) {
  if (segments.free_states()) {
    return EvaluateSequences(segments, first, last, jacobians, share, out);
  }
  const int np = segments.np(), nm = segments.nm();
  const int n = np + nm, size = segments.num_segments();
  // the owned segments at the new point, in the simulators' batches
  std::vector<const double*> x0(size, nullptr);
  for (int s = first; s < last; ++s) x0[s] = segments.X0(s);
  segments.Prefetch(x0, jacobians);
  bool ok = true;
  int warned = -1;
  std::vector<const double*> params;
  if (np) params.push_back(segments.z().data());
  if (nm) params.push_back(segments.m().data());
  share->costs.resize(std::max(last - first, 0));
  share->sums.assign(std::max(last - first, 0), 0.0);
  share->blocks.resize(std::max(last - first, 0));
  for (int s = first; s < last && ok; ++s) {
    // the sensor rows (all blocks) and the fitted-state rows (z only)
    auto& costs = share->costs[s - first];
    if (!costs[0]) {
      costs[0] = segments.SensorCost(s);
      costs[1] = segments.StateCost(s);
    }
    share->block.Reset(n);
    for (const auto& cost : costs) {
      if (!cost || cost->num_residuals() == 0 || !ok) continue;
      const int rows = cost->num_residuals();
      const int nblocks = static_cast<int>(cost->parameter_block_sizes().size());
      share->r.resize(rows);
      share->Jz.resize(rows, np);
      share->Jm.resize(rows, nm);
      double* jac[2] = {np ? share->Jz.data() : share->Jm.data(), share->Jm.data()};
      ok = cost->Evaluate(params.data(), share->r.data(), jacobians ? jac : nullptr) &&
           share->r.allFinite();
      if (!ok) break;
      share->sums[s - first] += share->r.squaredNorm();
      if (jacobians) {
        share->J.resize(rows, n);
        if (np) share->J.leftCols(np) = share->Jz;
        if (nm && nblocks > (np ? 1 : 0)) {
          share->J.rightCols(nm) = share->Jm;
        } else if (nm) {
          share->J.rightCols(nm).setZero();  // state rows do not depend on the measurement terms
        }
        share->block.Add(share->J, share->r);
      }
    }
    if (jacobians) share->blocks[s - first] = share->block.Augmented();
    if (warned < 0 && segments.JacobianWarning(s)) warned = s;
  }
  Reply(segments, ok, warned, first, last, size, jacobians, *share, out);
}

// The one residual block of the segments on rank 0: the root of the tree, n + 1 rows on the
// blocks z, m (shards.h)
class TreeCost : public ceres::CostFunction {
 public:
  TreeCost(const ShardedResiduals* shards, int np, int nm) : shards_(shards) {
    set_num_residuals(np + nm + 1);
    if (np) mutable_parameter_block_sizes()->push_back(np);
    if (nm) mutable_parameter_block_sizes()->push_back(nm);
  }

  bool Evaluate(double const* const* /*parameters*/, double* residuals,
                double** jacobians) const override {
    const ShardedResiduals::Root& g = shards_->root();
    const int n = shards_->n();
    if (!g.ok) return false;
    MJSYSID_DEMAND(!jacobians || g.jacobians, "Jacobians asked without the callback");
    // as a compressed block (sysid/solve/compressed_cost.h): z columns, then m columns
    if (!g.jacobians) {
      WriteNorm(n, g.sum_squares, residuals);
      return true;
    }
    WriteTriangle(g.r_aug, g.r_aug(n, n), parameter_block_sizes(), residuals, jacobians);
    return true;
  }

 private:
  const ShardedResiduals* shards_;
};

// The state blocks of the sequences [first, last), concatenated in block order (the blocks of a
// sequence follow those of the one before), gathered to rank 0: every rank's in rank order is
// every block in order
std::vector<double> OwnStates(const SegmentEvaluator& segments, int first, int last) {
  std::vector<double> out;
  for (int s = 0; s < segments.num_segments(); ++s) {
    const Segment& seg = segments.segment(s);
    if (seg.block < 0 || seg.seq < first || seg.seq >= last) continue;
    const auto x = segments.states()[seg.block];
    out.insert(out.end(), x.begin(), x.end());
  }
  return out;
}
void SendStates(const SegmentEvaluator& segments, int first, int last) {
  std::vector<double> send = OwnStates(segments, first, last);
  int count = static_cast<int>(send.size());
  MPI_Gather(&count, 1, MPI_INT, nullptr, 0, MPI_INT, 0, MPI_COMM_WORLD);
  MPI_Gatherv(send.data(), count, MPI_DOUBLE, nullptr, nullptr, nullptr, MPI_DOUBLE, 0,
              MPI_COMM_WORLD);
}

}  // namespace

// -----------------------------------------------------------------------------------------------
// session

void Initialize(int* argc, char*** argv) {
  if (g_initialized) return;
  if (!std::getenv("OMPI_COMM_WORLD_SIZE") && !std::getenv("PMI_SIZE") &&
      !std::getenv("PMIX_RANK")) {
    return;  // not started by an MPI launcher
  }
  int provided = 0;
  MPI_Init_thread(argc, argv, MPI_THREAD_FUNNELED, &provided);
  g_initialized = true;
}

void Finalize() {
  if (!g_initialized || g_finalized) return;
  g_finalized = true;
  MPI_Finalize();
}

bool Active() { return g_initialized && !g_finalized; }

int Rank() {
  int rank = 0;
  if (g_initialized && !g_finalized) MPI_Comm_rank(MPI_COMM_WORLD, &rank);
  return rank;
}

int Size() {
  int size = 1;
  if (g_initialized && !g_finalized) MPI_Comm_size(MPI_COMM_WORLD, &size);
  return size;
}

std::string RankName(int rank) {
  // the host of `rank`: each rank knows its own; gathered once here (a collective call)
  char name[MPI_MAX_PROCESSOR_NAME] = {0};
  int len = 0;
  MPI_Get_processor_name(name, &len);
  std::vector<char> all(static_cast<size_t>(Size()) * MPI_MAX_PROCESSOR_NAME);
  MPI_Allgather(name, MPI_MAX_PROCESSOR_NAME, MPI_CHAR, all.data(), MPI_MAX_PROCESSOR_NAME,
                MPI_CHAR, MPI_COMM_WORLD);
  return "rank " + std::to_string(rank) + " on host " +
         std::string(all.data() + static_cast<size_t>(rank) * MPI_MAX_PROCESSOR_NAME);
}

bool AgreeReady(bool ok, const std::string& message, std::string* failure) {
  // the lowest failing rank (size: none), then its message from it
  const int size = Size(), rank = Rank();
  int mine = ok ? size : rank, first = size;
  MPI_Allreduce(&mine, &first, 1, MPI_INT, MPI_MIN, MPI_COMM_WORLD);
  if (first == size) return true;
  const std::string who = RankName(first);
  int len = rank == first ? static_cast<int>(message.size()) : 0;
  MPI_Bcast(&len, 1, MPI_INT, first, MPI_COMM_WORLD);
  std::string text = rank == first ? message : std::string(len, ' ');
  MPI_Bcast(text.data(), len, MPI_CHAR, first, MPI_COMM_WORLD);
  if (failure) *failure = who + ": " + text;
  return false;
}

void AgreeMoves(const SegmentEvaluator& segments) {
  // or over the ranks (max of 0/1)
  const std::vector<bool>& moves = segments.moves();
  std::vector<int> mine(segments.np(), 0), all(segments.np(), 0);
  for (size_t g = 0; g < mine.size() && g < moves.size(); ++g) mine[g] = moves[g];
  MPI_Allreduce(mine.data(), all.data(), static_cast<int>(mine.size()), MPI_INT, MPI_MAX,
                MPI_COMM_WORLD);
  segments.CheckMoves(std::vector<bool>(all.begin(), all.end()));
}

std::vector<int> SequenceRanges(const std::vector<double>& work, int ranks) {
  return ShardRanges(work, ranks);
}

std::vector<int> SequenceRanges(const SegmentEvaluator& segments, int ranks) {
  std::vector<double> work;
  for (int q = 0; q < segments.num_sequences(); ++q) work.push_back(segments.SequenceWork(q));
  return SequenceRanges(work, ranks);
}

std::vector<bool> OwnedSequences(const std::vector<double>& work, int rank, int ranks) {
  const std::vector<int> ranges = SequenceRanges(work, ranks);
  std::vector<bool> owned(work.size(), false);
  for (int q = ranges[rank]; q < ranges[rank + 1]; ++q) owned[q] = true;
  return owned;
}

int Leaves(const SegmentEvaluator& segments) {
  return segments.free_states() ? segments.num_sequences() : segments.num_segments();
}

std::vector<int> LeafRanges(const SegmentEvaluator& segments, int ranks) {
  return segments.free_states() ? SequenceRanges(segments, ranks) : SegmentRanges(segments, ranks);
}

std::vector<int> SegmentRanges(const SegmentEvaluator& segments, int ranks) {
  // the first segment of each rank's first sequence (segments are in sequence order)
  const std::vector<int> sequences = SequenceRanges(segments, ranks);
  std::vector<int> ranges;
  int s = 0;
  for (int q : sequences) {
    while (s < segments.num_segments() && segments.segment(s).seq < q) ++s;
    ranges.push_back(s);
  }
  return ranges;
}

// -----------------------------------------------------------------------------------------------
// rank 0

ShardedResiduals::ShardedResiduals() : share_(std::make_unique<Share>()) {}
ShardedResiduals::~ShardedResiduals() = default;

std::vector<bool> ShardedResiduals::OwnedSequences(const std::vector<double>& work) const {
  return mpi::OwnedSequences(work, Rank(), Size());
}

void ShardedResiduals::AddResidualBlocks(const SegmentEvaluator& segments, ceres::Problem* problem,
                                         const std::vector<double*>& blocks) {
  const bool first = !agreed_, refit = agreed_ && !new_problem_;
  new_problem_ = false;
  n_ = segments.np() + segments.nm();
  if (refit) {
    // a refit of the same input (auto's segments, Problem::Fit calling itself): the workers
    // prepare again with its segment length; they agreed on the input before
    command_.assign(kHeader + n_, 0.0);
    command_[0] = kPrepare;
    command_[1] = segments.segment_steps();
    MPI_Bcast(command_.data(), static_cast<int>(command_.size()), MPI_DOUBLE, 0, MPI_COMM_WORLD);
  }
  if (first) {
    std::string failure;
    agreed_ = true;
    if (!AgreeReady(true, "", &failure)) {
      done_ = true;
      throw RankError(failure);
    }
    // the checks over every rank's sequences: a failure ends every rank here (ParameterError)
    try {
      AgreeMoves(segments);
    } catch (...) {
      done_ = true;
      throw;
    }
  }
  if (!refit && (!first || problems_ > 1)) {
    // a start of --starts after the first problem (sysid/run/multi_start.h): the workers build
    // the same Problem at its start values (physical, in the parameter slots) and prepare it; the
    // ranks agree on readiness and on the parameters' effect as before the first fit (a failure
    // fails this start only)
    command_.assign(kHeader + n_, 0.0);
    command_[0] = kStart;
    const std::vector<double> initial = segments.InitialValues();
    std::copy(initial.begin(), initial.end(), command_.begin() + kHeader);
    MPI_Bcast(command_.data(), static_cast<int>(command_.size()), MPI_DOUBLE, 0, MPI_COMM_WORLD);
    std::string failure;
    if (!AgreeReady(true, "", &failure)) throw RankError(failure);
    AgreeMoves(segments);
  }
  share_ = std::make_unique<Share>();
  segments_.emplace(segments);
  const int np = segments.np(), nm = segments.nm();
  n_ = np + nm;
  ranges_ = LeafRanges(segments, Size());
  rows_ = 0;
  eliminated_ = 0;
  for (int s = 0; s < segments.num_segments(); ++s) {
    if (segments.segment(s).block >= 0) eliminated_ += segments.dims(s).nx;
    rows_ += segments.SensorCost(s)->num_residuals();
    if (const auto state_cost = segments.StateCost(s)) rows_ += state_cost->num_residuals();
  }
  problem->AddResidualBlock(new TreeCost(this, np, nm), nullptr, blocks);
}

void ShardedResiduals::PrepareForEvaluation(bool evaluate_jacobians,
                                            bool /*new_evaluation_point*/) {
  SegmentEvaluator& shard = *segments_;
  const int size = Size(), segments = Leaves(shard);
  // the command and the values, from the parameter blocks Ceres has updated
  auto t0 = std::chrono::steady_clock::now();
  command_.assign({kEvaluate, evaluate_jacobians ? 1.0 : 0.0});
  command_.insert(command_.end(), shard.z().begin(), shard.z().end());
  command_.insert(command_.end(), shard.m().begin(), shard.m().end());
  MPI_Bcast(command_.data(), static_cast<int>(command_.size()), MPI_DOUBLE, 0, MPI_COMM_WORLD);
  stats_.seconds_mpi += Seconds(t0);
  // rank 0's own share
  t0 = std::chrono::steady_clock::now();
  EvaluateShare(shard, ranges_[0], ranges_[1], evaluate_jacobians, share_.get(), &send_);
  stats_.seconds_own_share += Seconds(t0);
  // every rank's tree nodes (their sizes first)
  t0 = std::chrono::steady_clock::now();
  // [size, stopped] of every rank: a worker that caught a stop signal stops the fit after this
  // iteration, as rank 0's own signal does
  const int head[2] = {static_cast<int>(send_.size()), 0};
  heads_.assign(2 * size, 0);
  MPI_Gather(head, 2, MPI_INT, heads_.data(), 2, MPI_INT, 0, MPI_COMM_WORLD);
  counts_.assign(size, 0);
  for (int r = 0; r < size; ++r) {
    counts_[r] = heads_[2 * r];
    if (heads_[2 * r + 1] && interrupt_) interrupt_->store(true);
  }
  displs_.assign(size, 0);
  for (int r = 1; r < size; ++r) displs_[r] = displs_[r - 1] + counts_[r - 1];
  receive_.resize(static_cast<size_t>(displs_[size - 1] + counts_[size - 1]));
  MPI_Gatherv(send_.data(), head[0], MPI_DOUBLE, receive_.data(), counts_.data(), displs_.data(),
              MPI_DOUBLE, 0, MPI_COMM_WORLD);
  stats_.seconds_mpi += Seconds(t0);
  stats_.evaluations += 1;
  stats_.jacobian_evaluations += evaluate_jacobians ? 1 : 0;
  stats_.bytes += static_cast<long long>(size - 1) *
                  static_cast<long long>(sizeof(double) * command_.size() + 2 * sizeof(int));
  for (int r = 1; r < size; ++r) stats_.bytes += sizeof(double) * counts_[r];
  // the root from the nodes of every rank (the same bits with any number of ranks)
  root_.ok = true;
  root_.jacobians = evaluate_jacobians;
  const int width = evaluate_jacobians ? (n_ + 1) * (n_ + 1) : 1;
  std::map<std::pair<int, int>, const double*> nodes;
  for (int r = 0; r < size; ++r) {
    const double* in = receive_.data() + displs_[r];
    if (in[0] != 1.0) {
      root_.ok = false;
      shard.NoteRejection("the simulation of a sequence of rank " + std::to_string(r) +
                          " failed or was not finite at the trial point");
      continue;
    }
    const int warned = static_cast<int>(in[1]), step = static_cast<int>(in[2]);
    if (warned >= 0 && r > 0) {
      // the step it names, for auto's refit in segments (SegmentStepsAfterWarning)
      shard.NoteJacobianWarning(
          warned, "the core flagged this sequence's Jacobian on rank " + std::to_string(r) +
                      (step >= 0 ? " from step " + std::to_string(step) : ""));
    }
    const double* node = in + kReplyHeader;
    for (int k = 0; k < static_cast<int>(in[3]); ++k, node += 2 + width) {
      nodes[{static_cast<int>(node[0]), static_cast<int>(node[1])}] = node + 2;
    }
  }
  if (!root_.ok || segments == 0) return;
  if (evaluate_jacobians) {
    std::map<std::pair<int, int>, Eigen::MatrixXd> values;
    for (const auto& [key, data] : nodes) {
      values[key] = Eigen::Map<const Eigen::MatrixXd>(data, n_ + 1, n_ + 1);
    }
    root_.r_aug = ReduceTree<Eigen::MatrixXd>(
        0, segments,
        [&](int lo, int hi) {
          const auto it = values.find({lo, hi});
          return it == values.end() ? nullptr : &it->second;
        },
        MergeBlocks);
  } else {
    root_.sum_squares = ReduceTree<double>(
        0, segments,
        [&](int lo, int hi) {
          const auto it = nodes.find({lo, hi});
          return it == nodes.end() ? nullptr : it->second;
        },
        [](double a, double b) { return a + b; });
  }
}

void ShardedResiduals::CollectStates(SegmentEvaluator& segments) {
  if (!segments.free_states() || done_ || !agreed_) return;
  const int size = Size();
  command_.assign(kHeader + n_, 0.0);
  command_[0] = kStates;
  MPI_Bcast(command_.data(), static_cast<int>(command_.size()), MPI_DOUBLE, 0, MPI_COMM_WORLD);
  // rank 0's own blocks, then the others' (SendStates)
  std::vector<double> mine = OwnStates(segments, ranges_[0], ranges_[1]);
  int count = static_cast<int>(mine.size());
  counts_.assign(size, 0);
  MPI_Gather(&count, 1, MPI_INT, counts_.data(), 1, MPI_INT, 0, MPI_COMM_WORLD);
  displs_.assign(size, 0);
  for (int r = 1; r < size; ++r) displs_[r] = displs_[r - 1] + counts_[r - 1];
  receive_.resize(static_cast<size_t>(displs_[size - 1] + counts_[size - 1]));
  MPI_Gatherv(mine.data(), count, MPI_DOUBLE, receive_.data(), counts_.data(), displs_.data(),
              MPI_DOUBLE, 0, MPI_COMM_WORLD);
  size_t at = 0;
  for (size_t b = 0; b < segments.states().size(); ++b) {
    const StateBlocks::View<double> x = segments.states()[b];
    MJSYSID_DEMAND(at + x.size() <= receive_.size(),
                   "the ranks sent fewer states than the fit has");
    std::copy(receive_.begin() + at, receive_.begin() + at + x.size(), x.begin());
    at += x.size();
  }
}

void ShardedResiduals::Finish() {
  if (done_) return;
  done_ = true;
  if (!agreed_) {
    std::string failure;
    agreed_ = true;
    AgreeReady(false, "rank 0 stopped before the fit", &failure);
    return;
  }
  command_.assign(kHeader + n_, 0.0);
  command_[0] = kFinish;
  MPI_Bcast(command_.data(), static_cast<int>(command_.size()), MPI_DOUBLE, 0, MPI_COMM_WORLD);
}

void ShardedResiduals::Abandon(const std::string& message) {
  if (done_) return;
  if (agreed_) return Finish();
  done_ = true;
  agreed_ = true;
  std::string failure;
  AgreeReady(false, message, &failure);
}

// -----------------------------------------------------------------------------------------------
// workers

int ServeFit(const io::ExperimentConfig* config, int threads, const std::string& failure) {
  // a stop signal ends the fit after the iteration (rank 0 decides), not this rank at once
  for (int s : kStopSignals) std::signal(s, OnWorkerStop);
  // the same problem as rank 0's, prepared (bad input is found here, on every rank)
  std::string error = failure;
  run::BuiltProblem bp;
  FitOptions options, base;        // as prepared now; as the experiment says
  std::unique_ptr<Problem> start;  // the current start's Problem (--starts), after the first
  std::optional<SegmentEvaluator> segments;  // the current start's, prepared
  if (config && error.empty()) {
    try {
      bp = run::BuildProblem(*config, threads);
      options = bp.options;
      options.verbose = false;
      base = options;
      // a sharded start: this rank's sequences only
      const int rank = Rank(), ranks = Size();
      ShardStart(bp.problem.get(), [rank, ranks](const std::vector<double>& work) {
        return OwnedSequences(work, rank, ranks);
      });
      segments.emplace(PrepareOnly(bp.problem.get(), options));
    } catch (const std::exception& e) {
      error = e.what();
    }
  }
  if (!AgreeReady(error.empty(), error, nullptr)) return 0;  // rank 0 reports it
  try {
    AgreeMoves(*segments);
  } catch (const std::exception&) {
    return 0;  // the same failure on rank 0, which reports it
  }
  const int rank = Rank(), n = segments->np() + segments->nm();
  std::vector<int> ranges = LeafRanges(*segments, Size());
  std::vector<double> command(kHeader + n), send;
  Share share;
  // evaluate at every point rank 0 sends, until it finishes
  for (;;) {
    MPI_Bcast(command.data(), kHeader + n, MPI_DOUBLE, 0, MPI_COMM_WORLD);
    if (command[0] == kFinish) break;
    if (command[0] == kStates) {
      SendStates(*segments, ranges[rank], ranges[rank + 1]);
      continue;
    }
    if (command[0] == kStart) {
      // the next start: bp's Problem at the start values, prepared; then the agreement
      std::string not_ready;
      std::optional<SegmentEvaluator> next;
      try {
        Eigen::VectorXd values(static_cast<Eigen::Index>(bp.parameters.size()));
        for (Eigen::Index j = 0; j < values.size(); ++j) values[j] = command[kHeader + j];
        start = run::ProblemFrom(bp, values);
        const int ranks = Size();
        ShardStart(start.get(), [rank, ranks](const std::vector<double>& work) {
          return OwnedSequences(work, rank, ranks);
        });
        options = base;
        next = PrepareOnly(start.get(), options);
      } catch (const std::exception& e) {
        not_ready = e.what();
      }
      segments.reset();  // the previous start's Problem is gone
      if (!AgreeReady(not_ready.empty(), not_ready, nullptr)) continue;  // rank 0 records it
      try {
        AgreeMoves(*next);
      } catch (const std::exception&) {
        continue;  // the same failure on rank 0
      }
      segments = next;
      ranges = LeafRanges(*segments, Size());
      share = Share();
      continue;
    }
    if (command[0] == kPrepare) {
      // auto's refit in segments: the same input prepared again with rank 0's segment length
      options.segment_steps = static_cast<int>(command[1]);
      try {
        segments.emplace(PrepareOnly((start ? start : bp.problem).get(), options));
      } catch (const std::exception& e) {
        // rank 0 prepared the same input with the same options
        BrokenInvariant((RankName(rank) + ": preparing the refit failed: " + e.what()).c_str(),
                        __FILE__, __LINE__);
      }
      ranges = LeafRanges(*segments, Size());
      share = Share();
      continue;
    }
    segments->SetVariables(command.data() + kHeader);
    EvaluateShare(*segments, ranges[rank], ranges[rank + 1], command[1] == 1.0, &share, &send);
    const int head[2] = {static_cast<int>(send.size()), g_stop ? 1 : 0};
    MPI_Gather(head, 2, MPI_INT, nullptr, 0, MPI_INT, 0, MPI_COMM_WORLD);
    MPI_Gatherv(send.data(), head[0], MPI_DOUBLE, nullptr, nullptr, nullptr, MPI_DOUBLE, 0,
                MPI_COMM_WORLD);
  }
  return 0;
}

}  // namespace mjsysid::mpi
