// A residual block handed to Ceres as its thin-QR triangle instead of row by row (single and
// multiple shooting, docs/numerics.md "Memory").
//
// CompressedCost wraps a cost function with m rows over parameter blocks of ambient sizes n_1 ..
// n_k (n = sum n_b) and stands for it with n + 1 rows. With Jacobians it evaluates the inner
// cost, folds its rows [J r] (J m x n, the blocks side by side) into the (n + 1) x (n + 1)
// triangle [R Q^T r; 0 rho] (RowTriangle, sysid/row_triangle.h) and returns the residuals (Q^T r,
// c) and the Jacobian [R; 0], row-major per block, c = sqrt(max(0, |r|^2 - |Q^T r|^2)) with |r|^2
// summed over the m rows; residuals only: (0, .., 0, |r|). Either way the block's cost is 0.5 |r|^2
// to rounding, and its gradient J^T r and Gauss-Newton matrix J^T J are those of the m rows, so
// Ceres' Levenberg-Marquardt steps, its Jacobi scaling (the column norms) and the cost it reports
// are those of the rows up to rounding. Ceres' manifolds act on the columns (J P), which commutes
// with the fold. Per-residual robust losses (FitOptions::loss) are applied inside the inner cost
// (sysid/residual_model.h RobustResidual: rows sign(e) sqrt(rho(e^2))), so they survive the fold;
// a Ceres LossFunction on the whole block would not (Problem adds none).
//
// The last fold: each block keeps its last fold with Jacobians (the triangle and c) with its
// inputs, every parameter block's values (bitwise) and CompressedBlocks::epoch; a request with
// Jacobians at the same inputs writes that fold out without calling the inner cost (the same bits
// as a re-fold: the statistical stop's test and the covariance ask at the point whose Jacobian
// Ceres just had folded, sysid/gn_convergence.h). The owner advances the epoch whenever anything
// else the inner cost reads may change; a residual-only evaluation at other values drops the fold;
// a failed evaluation keeps none. CompressedBlocks::reuse_folds = false: always re-fold.
//
// Memory: Ceres holds n + 1 rows per block, each block (n + 1)^2 + n doubles for its last fold;
// the inner cost's residuals and Jacobian live in a CompressedBlocks scratch shared by every block
// of a problem (sized to the largest block), so one block's rows exist at a time. Threads: the
// scratch makes Evaluate single-threaded (Ceres num_threads = 1, as Problem::Fit runs it).
// Failure: the inner cost's false is returned.
#pragma once

#include <ceres/ceres.h>

#include <cstdint>
#include <memory>
#include <vector>

#include "core/state.h"
#include "sysid/row_triangle.h"

namespace mjsysid {

// what the compressed blocks of one ceres::Problem share; must outlive the problem
struct CompressedBlocks {
  // the rows the compressed blocks stand for, less the rows Ceres sees (real rows = Ceres'
  // num_residuals + hidden_rows)
  long long hidden_rows = 0;
  // one evaluation's scratch: residuals (m), per-block Jacobians (m x n_b, row-major), a chunk of
  // rows [J r], the fold
  std::vector<double> r;
  std::vector<std::vector<double>> jacobians;
  std::vector<double*> jacobian_ptrs;
  RowMatrix chunk;
  RowTriangle triangle;
  // the last folds (see above): whether a block may write out its last fold, and the epoch of the
  // inputs besides the parameter values (borrowed, advanced by the owner; nullptr: always 0)
  bool reuse_folds = true;
  const std::uint64_t* epoch = nullptr;
  // evaluations with Jacobians: folds made, and last folds written out instead
  long long folds = 0;
  long long reused_folds = 0;
};

class CompressedCost : public ceres::CostFunction {
 public:
  // inner: the cost stood for (owned); blocks: the shared scratch (borrowed)
  CompressedCost(std::unique_ptr<ceres::CostFunction> inner, CompressedBlocks* blocks);

  bool Evaluate(double const* const* parameters, double* residuals,
                double** jacobians) const override;

  const ceres::CostFunction& inner() const { return *inner_; }

 private:
  // whether the last fold was made at parameters (bitwise) in the current epoch
  bool HoldsFoldAt(double const* const* parameters) const;
  // remembers parameters and the epoch as the last fold's inputs
  void KeepInputs(double const* const* parameters) const;

  std::unique_ptr<ceres::CostFunction> inner_;
  CompressedBlocks* blocks_;
  // the last fold with Jacobians: (n + 1) x (n + 1) triangle, c, and its inputs (the values of
  // every parameter block side by side, n; the epoch); allocated once
  mutable bool has_fold_ = false;
  mutable Eigen::MatrixXd fold_;
  mutable double fold_last_ = 0;
  mutable std::vector<double> fold_values_;
  mutable std::uint64_t fold_epoch_ = 0;
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
// owns it (blocks->hidden_rows counts the rows it hides); ownership of the result as of cost
ceres::CostFunction* Compress(ceres::CostFunction* cost, CompressedBlocks* blocks);

// the rows a residual block's cost function stands for: the inner cost's of a CompressedCost,
// else its own
int RealRows(const ceres::CostFunction& cost);

}  // namespace mjsysid
