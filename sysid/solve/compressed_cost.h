// A residual block handed to Ceres as its thin-QR triangle instead of row by row (single and
// multiple shooting, docs/numerics.md "Memory").
//
// CompressedCost wraps a cost function with m rows over parameter blocks of ambient sizes n_1 ..
// n_k (n = sum n_b) and stands for it with n + 1 rows. With Jacobians it evaluates the inner
// cost, folds its rows [J r] (J m x n, the blocks side by side) into the (n + 1) x (n + 1)
// triangle [R Q^T r; 0 rho] (RowTriangle, sysid/solve/row_triangle.h) and returns the residuals
// (Q^T r, c) and the Jacobian [R; 0], row-major per block, c = sqrt(max(0, |r|^2 - |Q^T r|^2)) with
// |r|^2 summed over the m rows; residuals only: (0, .., 0, |r|). Either way the block's cost is 0.5
// |r|^2 to rounding, and its gradient J^T r and Gauss-Newton matrix J^T J are those of the m rows,
// so Ceres' Levenberg-Marquardt steps, its Jacobi scaling (the column norms) and the cost it
// reports are those of the rows up to rounding. Ceres' manifolds act on the columns (J P), which
// commutes with the fold. Per-residual robust losses (FitOptions::loss) are applied inside the
// inner cost (sysid/solve/residual_model.h RobustResidual: rows sign(e) sqrt(rho(e^2))), so they
// survive the fold; a Ceres LossFunction on the whole block would not (Problem adds none).
//
// The last fold: each block keeps its last fold with Jacobians (the triangle and c) with its
// inputs, every parameter block's values (bitwise) and CompressedBlocks::epoch; a request with
// Jacobians at the same inputs writes that fold out without calling the inner cost (the same bits
// as a re-fold: the statistical stop's test and the covariance ask at the point whose Jacobian
// Ceres just had folded, sysid/solve/gn_convergence.h). The owner advances the epoch whenever
// anything else the inner cost reads may change; a residual-only evaluation at other values drops
// the fold; a failed evaluation keeps none. CompressedBlocks::reuse_folds = false: always re-fold.
//
// Folds ahead (FoldAhead): an inner cost that is a FoldableCost can have its rows made and folded
// before Ceres asks, on the simulator's workers, one task per block (the evaluation callback does
// it after each Jacobian batch, sysid/solve/cost_functions.h PrefetchCallback): each task writes
// its block's last fold with the inputs it was made at (the parameter blocks' values as Ceres then
// passes them: Ceres writes the point into the user's blocks before the callback), so that
// Ceres' Evaluate calls, one after the other on the fit thread, only write folds out. The fold is
// the same code on the same rows: the same bits as a fold at Evaluate, at any thread count. The
// inner cost's side effects (FoldableCost::NoteRows) are applied when Ceres first asks for the
// fold, in Ceres' order, as Evaluate applies them; a block whose rows fail ahead gets no fold, and
// Evaluate evaluates it as without folds ahead (failing the same way). A fold made ahead is
// written out once even with reuse_folds = false, and counts as a fold (folds) when it is, and
// in ahead_folds: folds and reused_folds are those of a fit without folds ahead.
//
// Memory: Ceres holds n + 1 rows per block, each block (n + 1)^2 + n doubles for its last fold;
// the inner cost's residuals and Jacobian live in a CompressedBlocks scratch shared by every block
// of a problem (sized to the largest block), so one block's rows exist at a time; folds ahead use
// one such scratch per worker. Threads: the scratch makes Evaluate single-threaded (Ceres
// num_threads = 1, as Problem::Fit runs it); FoldAhead runs on the fit thread and hands the blocks
// to the workers itself.
// Failure: the inner cost's false is returned.
#pragma once

#include <ceres/ceres.h>

#include <cstdint>
#include <functional>
#include <memory>
#include <vector>

#include "core/state.h"
#include "sysid/solve/row_triangle.h"

namespace mjsysid {

// one fold's scratch: the inner cost's residuals (m), per-block Jacobians (m x n_b, row-major), a
// chunk of rows [J r], the triangle; sized by the fold, reused
struct FoldScratch {
  std::vector<double> r;
  std::vector<std::vector<double>> jacobians;
  std::vector<double*> jacobian_ptrs;
  RowMatrix chunk;
  RowTriangle triangle;
};

class CompressedCost;

// what the compressed blocks of one ceres::Problem share; must outlive the problem
struct CompressedBlocks {
  // the rows the compressed blocks stand for, less the rows Ceres sees (real rows = Ceres'
  // num_residuals + hidden_rows)
  long long hidden_rows = 0;
  // scratch[0]: Evaluate's (one evaluation at a time); scratch[w]: worker w's in FoldAhead
  std::vector<FoldScratch> scratch = std::vector<FoldScratch>(1);
  // the last folds (see above): whether a block may write out its last fold, and the epoch of the
  // inputs besides the parameter values (borrowed, advanced by the owner; nullptr: always 0)
  bool reuse_folds = true;
  const std::uint64_t* epoch = nullptr;
  // folds ahead (see above): the blocks that can have them, each with the parameter blocks it was
  // added to the problem with (the user's pointers; Compress registers them)
  struct Member {
    const CompressedCost* cost = nullptr;
    std::vector<const double*> parameters;
  };
  std::vector<Member> members;
  // evaluations with Jacobians: folds made (ahead ones once written out), last folds written out
  // again instead, and of the folds those made ahead
  long long folds = 0;
  long long reused_folds = 0;
  long long ahead_folds = 0;
};

// An inner cost whose rows can be made ahead on a worker thread (see "Folds ahead"): Evaluate with
// Jacobians split into what reads or writes the fit's shared state (PrepareRows, NoteRows: the fit
// thread) and the rows themselves (Rows: any thread).
class FoldableCost : public ceres::CostFunction {
 public:
  // fit thread: whether Rows can give now, at parameters, what Evaluate with Jacobians would (its
  // inputs ready: nothing to simulate, nothing shared to change); false: no fold ahead
  virtual bool PrepareRows(double const* const* parameters) const = 0;
  // any thread, after PrepareRows(parameters) returned true and before anything else runs on the
  // fit: Evaluate's residuals and every block's Jacobian (jacobians: all blocks) at parameters, bit
  // for bit, without its side effects; false (or a throw): Evaluate would fail there
  virtual bool Rows(double const* const* parameters, double* residuals,
                    double** jacobians) const = 0;
  // fit thread: Evaluate's side effects at the inputs of the last successful PrepareRows and Rows
  // (e.g. a warning noted); called when their fold is first written out
  virtual void NoteRows() const = 0;
};

class CompressedCost : public ceres::CostFunction {
 public:
  // inner: the cost stood for (owned); blocks: the shared scratch (borrowed)
  CompressedCost(std::unique_ptr<ceres::CostFunction> inner, CompressedBlocks* blocks);

  bool Evaluate(double const* const* parameters, double* residuals,
                double** jacobians) const override;

  const ceres::CostFunction& inner() const { return *inner_; }
  // the inner cost as a FoldableCost, or nullptr: no folds ahead
  const FoldableCost* foldable() const { return foldable_; }

  // the fold ahead (see "Folds ahead") at parameters into this block's last fold, with scratch;
  // false: the rows failed (no fold kept). Any thread, one task per block, after
  // foldable()->PrepareRows(parameters) returned true on the fit thread.
  bool FoldAheadAt(double const* const* parameters, FoldScratch* scratch) const;
  // whether the last fold was made at parameters (bitwise) in the current epoch and may be
  // written out
  bool HoldsFoldAt(double const* const* parameters) const;

 private:
  // the inner rows at parameters (from Rows when ahead, else the inner Evaluate) folded into the
  // last fold; false: the inner cost failed, no fold kept
  bool Fold(double const* const* parameters, FoldScratch* scratch, bool ahead) const;
  // remembers parameters and the epoch as the last fold's inputs
  void KeepInputs(double const* const* parameters) const;

  std::unique_ptr<ceres::CostFunction> inner_;
  const FoldableCost* foldable_;  // inner_ as a FoldableCost, or nullptr
  CompressedBlocks* blocks_;
  // the last fold with Jacobians: (n + 1) x (n + 1) triangle, c, and its inputs (the values of
  // every parameter block side by side, n; the epoch); allocated once
  mutable bool has_fold_ = false;
  mutable Eigen::MatrixXd fold_;
  mutable double fold_last_ = 0;
  mutable std::vector<double> fold_values_;
  mutable std::uint64_t fold_epoch_ = 0;
  // the last fold was made ahead and has not been written out yet (its NoteRows pending)
  mutable bool ahead_ = false;
};

// Ceres' view of a folded block (also the MPI root's, sysid/mpi/distributed_fit.h): residuals
// r_aug.col(n) with the last (rho) replaced by `last`, and the Jacobian r_aug.leftCols(n)
// row-major per parameter block of `sizes` (n = sum sizes; jacobians or any of its blocks may be
// nullptr: not written). r_aug: (n + 1) x (n + 1), [R Q^T r; 0 rho].
void WriteTriangle(const Eigen::MatrixXd& r_aug, double last, const std::vector<int32_t>& sizes,
                   double* residuals, double** jacobians);
// a residual-only evaluation's n + 1 values: n zeros and sqrt(sum_squares) (any values of that
// norm give the cost)
void WriteNorm(int n, double sum_squares, double* residuals);

// cost itself when it has no more rows than its triangle (m <= n + 1), else a CompressedCost that
// owns it (blocks->hidden_rows counts the rows it hides); ownership of the result as of cost.
// parameters: the parameter blocks the result is added to the problem with; given, a
// CompressedCost of a FoldableCost joins blocks->members (folds ahead)
ceres::CostFunction* Compress(ceres::CostFunction* cost, CompressedBlocks* blocks,
                              const std::vector<double*>& parameters = {});

// Folds ahead (see above) for every member block whose last fold is not at its parameter blocks'
// current values, whose inner cost's PrepareRows agrees: one task per block, run by
// parallel_for(n, task) (task(worker, i) for every i < n, worker < workers, e.g. the simulator's
// pool: Simulator::ParallelFor), each block's fold into its own last fold. Fit thread. Returns the
// blocks folded.
int FoldAhead(CompressedBlocks* blocks, int workers,
              const std::function<void(int, const std::function<void(int, int)>&)>& parallel_for);

// the rows a residual block's cost function stands for: the inner cost's of a CompressedCost,
// else its own
int RealRows(const ceres::CostFunction& cost);

}  // namespace mjsysid
