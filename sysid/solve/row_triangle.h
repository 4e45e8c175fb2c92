// The one QR fold of the code base: the thin-QR triangle of a tall matrix whose rows arrive in
// blocks, without holding the rows. Users: the Jacobian at a fit's estimate
// (sysid/assess/estimate_jacobian.h), the compressed residual blocks of one process
// (sysid/solve/compressed_cost.h) and of MPI ranks (sysid/mpi/shards.h).
//
// After blocks M_1 .. M_k (each rows_i x n, row-major) R() is upper triangular, min(rows, n) x n
// (column-major), with R^T R = sum M_i^T M_i (the same normal matrix, so the same least-squares
// solutions, singular values and right singular vectors as the stacked matrix). Each block is
// taken in chunks of kChunkRows rows: Householder QR of [R; chunk], in place. Memory O(n (n +
// kChunkRows)) whatever the rows; the chunks are fixed by the rows added, so the result is the
// same bits for the same blocks (no dependence on threads or on how a caller splits a block into
// the two forms of Add). A column scaling commutes: the R of M D is R D.
//
// For least squares the rows are [J r] (n - 1 columns of J, the residuals last): R = [R_J Q^T r;
// 0 rho] with |Q^T r|^2 + rho^2 = |r|^2, so [R_J; 0] and (Q^T r, rho) give the cost 0.5 |r|^2,
// the gradient J^T r and the Gauss-Newton matrix J^T J of every row added.
#pragma once

#include <Eigen/Core>
#include <cstdint>

#include "core/state.h"

namespace mjsysid {

class RowTriangle {
 public:
  static constexpr int kChunkRows = 1024;
  explicit RowTriangle(int n = 0);
  // forgets every row, width n
  void Reset(int n);
  // adds rows (rows x n, row-major); n must match (else std::invalid_argument)
  void Add(const Eigen::Ref<const RowMatrix>& rows);
  // adds the rows [J r]: J rows x (n - 1), r rows (the same bits as Add of the joined rows)
  void Add(const Eigen::Ref<const RowMatrix>& J, const Eigen::Ref<const Eigen::VectorXd>& r);
  const Eigen::MatrixXd& R() const { return r_; }
  // R with zero rows below it: n x n, upper triangular
  Eigen::MatrixXd Square() const;
  int64_t rows() const { return rows_; }  // rows added
  int n() const { return n_; }

 private:
  // the chunk of count rows the caller wrote below R into stacked_ (Stack) folded into R
  void Stack(Eigen::Index count);
  void Fold(Eigen::Index count);

  int n_ = 0;
  int64_t rows_ = 0;
  Eigen::MatrixXd r_;        // min(rows_, n_) x n_
  Eigen::MatrixXd stacked_;  // [R; chunk], reused
};

}  // namespace mjsysid
