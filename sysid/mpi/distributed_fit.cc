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

#include "core/invariant.h"
#include "sysid/fit/prepare.h"
#include "sysid/mpi/state_projection.h"
#include "sysid/run/fit_experiment.h"
#include "sysid/run/multi_start.h"
#include "sysid/solve/compressed_cost.h"
#include "sysid/solve/cost_functions.h"
#include "sysid/solve/multiple_shooting.h"
#include "sysid/solve/state_residuals.h"

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
void Reply(const FitDiagnostics& diag, bool ok, int warned, int first, int last, int leaves,
           bool jacobians, const Share& share, std::vector<double>* out) {
  const int step = warned >= 0 ? WarningStep(diag.jacobian_warnings.at(warned)) : -1;
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

// EvaluateShare (below) with free states (BySequence): the leaves [first, last) are whole
// sequences, each solved for its states and reduced by StateProjection
void EvaluateSequences(const FitParts& parts, int first, int last, bool jacobians, Share* share,
                       std::vector<double>* out) {
  const PreparedFit& fit = *parts.fit;
  const FitDiagnostics& diag = *parts.diag;
  if (!share->projection) share->projection = std::make_unique<StateProjection>(parts);
  const int leaves = static_cast<int>(fit.sequences.size());
  share->sums.assign(std::max(last - first, 0), 0.0);
  share->blocks.resize(std::max(last - first, 0));
  bool ok = true;
  int warned = -1;
  for (int q = first; q < last && ok; ++q) {
    ok = share->projection->Solve(q, jacobians, &share->blocks[q - first], &share->sums[q - first]);
    for (size_t s = 0; s < fit.segments.size() && warned < 0; ++s) {
      if (fit.segments[s].seq == q && diag.jacobian_warnings.count(static_cast<int>(s))) {
        warned = static_cast<int>(s);
      }
    }
  }
  Reply(diag, ok, warned, first, last, leaves, jacobians, *share, out);
}

// One rank's share at the variables (z, m): its segments [first, last) simulated
// (batched), their sensor and state residuals evaluated and, with Jacobians, compressed one
// segment at a time; then the values of the maximal tree nodes of its range (shards.h). out:
// [ok, warned segment (-1: none), number of nodes, then per node: lo, hi and its value (sum r^2,
// or R_aug column-major with Jacobians)].
void EvaluateShare(const FitParts& parts, int first, int last, bool jacobians, Share* share,
                   std::vector<double>* out) {
  const PreparedFit& fit = *parts.fit;
  const FitVariables& vars = *parts.vars;
  const FitDiagnostics& diag = *parts.diag;
  if (BySequence(fit)) return EvaluateSequences(parts, first, last, jacobians, share, out);
  const int np = static_cast<int>(vars.z.size()), nm = static_cast<int>(vars.m.size());
  const int n = np + nm, size = static_cast<int>(fit.segments.size());
  // the owned segments at the new point, in the simulators' batches
  std::vector<const double*> x0(fit.segments.size(), nullptr);
  for (int s = first; s < last; ++s) x0[s] = fit.X0(vars.states, s);
  parts.solve->cache->Prefetch(np ? vars.z.data() : nullptr, x0, jacobians);
  bool ok = true;
  int warned = -1;
  std::vector<const double*> params;
  if (np) params.push_back(vars.z.data());
  if (nm) params.push_back(vars.m.data());
  share->costs.resize(std::max(last - first, 0));
  share->sums.assign(std::max(last - first, 0), 0.0);
  share->blocks.resize(std::max(last - first, 0));
  for (int s = first; s < last && ok; ++s) {
    // the sensor rows (all blocks) and the fitted-state rows (z only)
    auto& costs = share->costs[s - first];
    if (!costs[0]) {
      costs[0] = std::make_unique<SegmentCost>(parts, s);
      if (fit.segments[s].state_rows) costs[1] = std::make_unique<StateCost>(parts, s);
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
    if (warned < 0 && diag.jacobian_warnings.count(s)) warned = s;
  }
  Reply(diag, ok, warned, first, last, size, jacobians, *share, out);
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
std::vector<double> OwnStates(const PreparedFit& fit, const FitVariables& vars, int first,
                              int last) {
  std::vector<double> out;
  for (const Segment& seg : fit.segments) {
    if (seg.block < 0 || seg.seq < first || seg.seq >= last) continue;
    out.insert(out.end(), vars.states[seg.block].begin(), vars.states[seg.block].end());
  }
  return out;
}
void SendStates(const PreparedFit& fit, const FitVariables& vars, int first, int last) {
  std::vector<double> send = OwnStates(fit, vars, first, last);
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

void AgreeMoves(const PreparedFit& fit) {
  // or over the ranks (max of 0/1)
  std::vector<int> mine(fit.params.size(), 0), all(fit.params.size(), 0);
  for (size_t g = 0; g < mine.size() && g < fit.moves.size(); ++g) mine[g] = fit.moves[g];
  MPI_Allreduce(mine.data(), all.data(), static_cast<int>(mine.size()), MPI_INT, MPI_MAX,
                MPI_COMM_WORLD);
  CheckParametersMove(fit, std::vector<bool>(all.begin(), all.end()));
}

std::vector<int> SequenceRanges(const PreparedFit& fit, int ranks) {
  std::vector<double> cost;
  for (size_t q = 0; q < fit.sequences.size(); ++q) {
    const FitModel& mo = fit.models[fit.ModelIndex(fit.sequences[q].model)];
    const int columns = mo.sim->parameters().size() + 1;  // + the rollout
    cost.push_back(static_cast<double>(fit.grids[q].steps) * columns);
  }
  return ShardRanges(cost, ranks);
}

std::vector<bool> OwnedSequences(const PreparedFit& fit, int rank, int ranks) {
  const std::vector<int> ranges = SequenceRanges(fit, ranks);
  std::vector<bool> owned(fit.sequences.size(), false);
  for (int q = ranges[rank]; q < ranges[rank + 1]; ++q) owned[q] = true;
  return owned;
}

bool BySequence(const PreparedFit& fit) {
  for (const Segment& seg : fit.segments) {
    if (seg.block >= 0) return true;  // a free state (a state block)
  }
  return false;
}

int Leaves(const PreparedFit& fit) {
  return static_cast<int>(BySequence(fit) ? fit.sequences.size() : fit.segments.size());
}

std::vector<int> LeafRanges(const PreparedFit& fit, int ranks) {
  return BySequence(fit) ? SequenceRanges(fit, ranks) : SegmentRanges(fit, ranks);
}

std::vector<int> SegmentRanges(const PreparedFit& fit, int ranks) {
  // the first segment of each rank's first sequence (segments are in sequence order)
  const std::vector<int> sequences = SequenceRanges(fit, ranks);
  std::vector<int> ranges;
  int s = 0;
  for (int q : sequences) {
    while (s < static_cast<int>(fit.segments.size()) && fit.segments[s].seq < q) ++s;
    ranges.push_back(s);
  }
  return ranges;
}

// -----------------------------------------------------------------------------------------------
// rank 0

ShardedResiduals::ShardedResiduals() : share_(std::make_unique<Share>()) {}
ShardedResiduals::~ShardedResiduals() = default;

std::vector<bool> ShardedResiduals::OwnedSequences(const PreparedFit& fit) const {
  return mpi::OwnedSequences(fit, Rank(), Size());
}

void ShardedResiduals::AddResidualBlocks(const FitParts& parts, ceres::Problem* problem,
                                         const std::vector<double*>& blocks) {
  const bool first = !agreed_, refit = agreed_ && !new_problem_;
  new_problem_ = false;
  const PreparedFit& fit = *parts.fit;
  const FitVariables& vars = *parts.vars;
  n_ = static_cast<int>(vars.z.size() + vars.m.size());
  if (refit) {
    // a refit of the same input (auto's segments, Problem::Fit calling itself): the workers
    // prepare again with its segment length; they agreed on the input before
    command_.assign(kHeader + n_, 0.0);
    command_[0] = kPrepare;
    command_[1] = fit.options.segment_steps;
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
      AgreeMoves(fit);
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
    for (size_t j = 0; j < fit.params.size(); ++j) command_[kHeader + j] = fit.params[j].initial;
    MPI_Bcast(command_.data(), static_cast<int>(command_.size()), MPI_DOUBLE, 0, MPI_COMM_WORLD);
    std::string failure;
    if (!AgreeReady(true, "", &failure)) throw RankError(failure);
    AgreeMoves(fit);
  }
  share_ = std::make_unique<Share>();
  parts_ = parts;
  const int np = static_cast<int>(vars.z.size()), nm = static_cast<int>(vars.m.size());
  n_ = np + nm;
  ranges_ = LeafRanges(fit, Size());
  rows_ = 0;
  eliminated_ = 0;
  for (size_t s = 0; s < fit.segments.size(); ++s) {
    const Segment& seg = fit.segments[s];
    if (seg.block >= 0) eliminated_ += fit.models[seg.model].sim->dims().nx;
    rows_ += SegmentCost(parts, static_cast<int>(s)).num_residuals();
    if (fit.segments[s].state_rows) {
      rows_ += StateCost(parts, static_cast<int>(s)).num_residuals();
    }
  }
  problem->AddResidualBlock(new TreeCost(this, np, nm), nullptr, blocks);
}

void ShardedResiduals::PrepareForEvaluation(bool evaluate_jacobians,
                                            bool /*new_evaluation_point*/) {
  const FitVariables& vars = *parts_.vars;
  FitDiagnostics& diag = *parts_.diag;
  const int size = Size(), segments = Leaves(*parts_.fit);
  // the command and the values, from the parameter blocks Ceres has updated
  auto t0 = std::chrono::steady_clock::now();
  command_.assign({kEvaluate, evaluate_jacobians ? 1.0 : 0.0});
  command_.insert(command_.end(), vars.z.begin(), vars.z.end());
  command_.insert(command_.end(), vars.m.begin(), vars.m.end());
  MPI_Bcast(command_.data(), static_cast<int>(command_.size()), MPI_DOUBLE, 0, MPI_COMM_WORLD);
  stats_.seconds_mpi += Seconds(t0);
  // rank 0's own share
  t0 = std::chrono::steady_clock::now();
  EvaluateShare(parts_, ranges_[0], ranges_[1], evaluate_jacobians, share_.get(), &send_);
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
      diag.NoteRejection("the simulation of a sequence of rank " + std::to_string(r) +
                         " failed or was not finite at the trial point");
      continue;
    }
    const int warned = static_cast<int>(in[1]), step = static_cast<int>(in[2]);
    if (warned >= 0 && r > 0) {
      // the step it names, for auto's refit in segments (SegmentStepsAfterWarning)
      diag.NoteJacobianWarning(warned, "the core flagged this sequence's Jacobian on rank " +
                                           std::to_string(r) +
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

void ShardedResiduals::CollectStates(const FitParts& parts) {
  const PreparedFit& fit = *parts.fit;
  FitVariables& vars = *parts.vars;
  if (!BySequence(fit) || done_ || !agreed_) return;
  const int size = Size();
  command_.assign(kHeader + n_, 0.0);
  command_[0] = kStates;
  MPI_Bcast(command_.data(), static_cast<int>(command_.size()), MPI_DOUBLE, 0, MPI_COMM_WORLD);
  // rank 0's own blocks, then the others' (SendStates)
  std::vector<double> mine = OwnStates(fit, vars, ranges_[0], ranges_[1]);
  int count = static_cast<int>(mine.size());
  counts_.assign(size, 0);
  MPI_Gather(&count, 1, MPI_INT, counts_.data(), 1, MPI_INT, 0, MPI_COMM_WORLD);
  displs_.assign(size, 0);
  for (int r = 1; r < size; ++r) displs_[r] = displs_[r - 1] + counts_[r - 1];
  receive_.resize(static_cast<size_t>(displs_[size - 1] + counts_[size - 1]));
  MPI_Gatherv(mine.data(), count, MPI_DOUBLE, receive_.data(), counts_.data(), displs_.data(),
              MPI_DOUBLE, 0, MPI_COMM_WORLD);
  size_t at = 0;
  for (size_t b = 0; b < vars.states.size(); ++b) {
    const StateBlocks::View<double> x = vars.states[b];
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
  FitParts parts{};                // the current start's, prepared (parts.fit null: none)
  if (config && error.empty()) {
    try {
      bp = run::BuildProblem(*config, threads);
      options = bp.options;
      options.verbose = false;
      base = options;
      // a sharded start: this rank's sequences only
      const int rank = Rank(), ranks = Size();
      ShardStart(bp.problem.get(), [rank, ranks](const PreparedFit& fit) {
        return OwnedSequences(fit, rank, ranks);
      });
      parts = PrepareOnly(bp.problem.get(), options);
    } catch (const std::exception& e) {
      error = e.what();
    }
  }
  if (!AgreeReady(error.empty(), error, nullptr)) return 0;  // rank 0 reports it
  try {
    AgreeMoves(*parts.fit);
  } catch (const std::exception&) {
    return 0;  // the same failure on rank 0, which reports it
  }
  const int rank = Rank(), n = static_cast<int>(parts.vars->z.size() + parts.vars->m.size());
  std::vector<int> ranges = LeafRanges(*parts.fit, Size());
  std::vector<double> command(kHeader + n), send;
  Share share;
  // evaluate at every point rank 0 sends, until it finishes
  for (;;) {
    MPI_Bcast(command.data(), kHeader + n, MPI_DOUBLE, 0, MPI_COMM_WORLD);
    if (command[0] == kFinish) break;
    if (command[0] == kStates) {
      SendStates(*parts.fit, *parts.vars, ranges[rank], ranges[rank + 1]);
      continue;
    }
    if (command[0] == kStart) {
      // the next start: bp's Problem at the start values, prepared; then the agreement
      std::string not_ready;
      FitParts next{};
      try {
        Eigen::VectorXd values(static_cast<Eigen::Index>(bp.parameters.size()));
        for (Eigen::Index j = 0; j < values.size(); ++j) values[j] = command[kHeader + j];
        start = run::ProblemFrom(bp, values);
        const int ranks = Size();
        ShardStart(start.get(), [rank, ranks](const PreparedFit& fit) {
          return OwnedSequences(fit, rank, ranks);
        });
        options = base;
        next = PrepareOnly(start.get(), options);
      } catch (const std::exception& e) {
        not_ready = e.what();
      }
      parts = FitParts{};  // the previous start's Problem is gone
      if (!AgreeReady(not_ready.empty(), not_ready, nullptr)) continue;  // rank 0 records it
      try {
        AgreeMoves(*next.fit);
      } catch (const std::exception&) {
        continue;  // the same failure on rank 0
      }
      parts = next;
      ranges = LeafRanges(*parts.fit, Size());
      share = Share();
      continue;
    }
    if (command[0] == kPrepare) {
      // auto's refit in segments: the same input prepared again with rank 0's segment length
      options.segment_steps = static_cast<int>(command[1]);
      try {
        parts = PrepareOnly((start ? start : bp.problem).get(), options);
      } catch (const std::exception& e) {
        // rank 0 prepared the same input with the same options
        BrokenInvariant((RankName(rank) + ": preparing the refit failed: " + e.what()).c_str(),
                        __FILE__, __LINE__);
      }
      ranges = LeafRanges(*parts.fit, Size());
      share = Share();
      continue;
    }
    std::vector<double>& z = parts.vars->z;
    std::copy(command.begin() + kHeader, command.begin() + kHeader + z.size(), z.begin());
    std::copy(command.begin() + kHeader + z.size(), command.end(), parts.vars->m.begin());
    EvaluateShare(parts, ranges[rank], ranges[rank + 1], command[1] == 1.0, &share, &send);
    const int head[2] = {static_cast<int>(send.size()), g_stop ? 1 : 0};
    MPI_Gather(head, 2, MPI_INT, nullptr, 0, MPI_INT, 0, MPI_COMM_WORLD);
    MPI_Gatherv(send.data(), head[0], MPI_DOUBLE, nullptr, nullptr, nullptr, MPI_DOUBLE, 0,
                MPI_COMM_WORLD);
  }
  return 0;
}

}  // namespace mjsysid::mpi
