// The arithmetic of a fit sharded across MPI ranks (sysid/mpi/distributed_fit.h), without MPI:
// which rank owns which segment, and the compressed residual block each rank sends to rank 0.
//
// Compression. A segment's weighted residuals r_s (m_s rows) and their Jacobian J_s (m_s x n, n
// the fitted variables z then m) are reduced to the upper-triangular R_aug ((n + 1) x (n + 1)) of
// the thin QR of the augmented matrix [J_s r_s]: R_aug = [R_s, Q_s^T r_s; 0, rho_s] with R_s
// (n x n), Q_s^T r_s (n) and |rho_s| the norm of the part of r_s outside the range of J_s. As a
// Ceres residual block, residuals R_aug.col(n) and Jacobian R_aug.leftCols(n) (n + 1 rows) give
// exactly the cost 0.5 |r_s|^2, the gradient J_s^T r_s and the Gauss-Newton matrix J_s^T J_s of the
// m_s rows, so Levenberg-Marquardt steps on the compressed block equal those on the full Jacobian
// up to rounding. Two blocks merge into one by the R_aug of the two stacked (MergeBlocks).
//
// The same bits with any number of ranks. Segments are merged along one fixed binary tree over
// their indices [0, S) (node [lo, hi) has children [lo, mid) and [mid, hi), mid = (lo + hi) / 2),
// whatever the ranks: a rank owns a contiguous range of segments, sends the values of the maximal
// tree nodes inside its range (CanonicalNodes: at most 2 log2(range) of them) and rank 0 merges
// those up to the root (ReduceTree). Every merge is then the same floating-point operation on the
// same operands as on one rank, so the root, Ceres' whole path and the estimates are bitwise the
// same for 1, 2 or 512 ranks (and any thread count). Residual-only sums go the same way.
//
// Sharding: contiguous ranges of segments balanced by cost: segment s goes to the rank r with
// r / ranks <= (cost before s + cost of s / 2) / total cost < (r + 1) / ranks. Deterministic.
#pragma once

#include <Eigen/Core>
#include <vector>

#include "core/state.h"
#include "sysid/solve/row_triangle.h"

namespace mjsysid::mpi {

// the first segment of each rank and the end: ranks + 1 entries (see Sharding above); cost[] >= 0
std::vector<int> ShardRanges(const std::vector<double>& cost, int ranks);

// the maximal nodes [lo, hi) of the tree over [0, size) inside [first, last), in index order
std::vector<std::pair<int, int>> CanonicalNodes(int first, int last, int size);

// the value of node [lo, hi) of the tree: known(lo, hi) when it returns a value, else
// merge(value of [lo, mid), value of [mid, hi)); a leaf must be known
template <class T, class Known, class Merge>
T ReduceTree(int lo, int hi, const Known& known, const Merge& merge) {
  if (const T* v = known(lo, hi)) return *v;
  const int mid = (lo + hi) / 2;
  return merge(ReduceTree<T>(lo, mid, known, merge), ReduceTree<T>(mid, hi, known, merge));
}

// the R_aug of [a; b] (both (n + 1) x (n + 1) R_aug blocks; one RowTriangle fold of the two)
Eigen::MatrixXd MergeBlocks(const Eigen::MatrixXd& a, const Eigen::MatrixXd& b);

// a segment's rows [J r] folded by the RowTriangle of sysid/solve/row_triangle.h (width n + 1)
class CompressedBlock {
 public:
  // n: the fitted variables (columns of every J added)
  explicit CompressedBlock(int n = 0);
  void Reset(int n);
  // adds rows: J (rows x n, row-major) and r (rows)
  void Add(const Eigen::Ref<const RowMatrix>& J, const Eigen::Ref<const Eigen::VectorXd>& r);
  int n() const { return triangle_.n() - 1; }
  // R_aug, (n + 1) x (n + 1), upper triangular (zero rows below the fold's), column-major (as
  // sent)
  Eigen::MatrixXd Augmented() const { return triangle_.Square(); }

 private:
  RowTriangle triangle_;
};

// Eliminating a sequence's own states (multiple shooting sharded by whole sequences; a building
// block, not wired into the distributed fit yet: docs/cluster.md). With the k state columns of the
// sequence's segments first, the (k + n + 1)^2 R_aug of [J_x J_p r] (a CompressedBlock of width
// k + n) is [R_xx R_xp q_x; 0 R_pp q_p; 0 0 rho]. Its bottom-right (n + 1) x (n + 1) corner
// [R_pp q_p; 0 rho] is the Schur complement in QR form: R_pp^T R_pp = J_p^T J_p - J_p^T J_x
// (J_x^T J_x)^-1 J_x^T J_p, and |q_p|^2 + rho^2 = min over dx of |J_x dx + r|^2, the variable
// projection's reduced system at fixed p (exact when the states sit at their optimum for p,
// q_x = 0). It merges along the tree like any block. The states follow a parameter step dp by
// back-substitution: dx = -R_xx^-1 (R_xp dp + q_x), which with dp from the reduced system is the
// Gauss-Newton step of the full system. R_xx must be nonsingular (every state column seen).
struct EliminatedBlock {
  Eigen::MatrixXd reduced;  // (n + 1) x (n + 1): [R_pp q_p; 0 rho], upper triangular
  Eigen::MatrixXd R_xx;     // k x k, upper triangular
  Eigen::MatrixXd R_xp;     // k x n
  Eigen::VectorXd q_x;      // k
  // the states' step for the parameters' step dp (n): k values
  Eigen::VectorXd StateStep(const Eigen::Ref<const Eigen::VectorXd>& dp) const;
};
// r_aug: the (k + n + 1)^2 R_aug of a CompressedBlock whose first k columns are the states
EliminatedBlock EliminateStates(const Eigen::MatrixXd& r_aug, int k);

}  // namespace mjsysid::mpi
