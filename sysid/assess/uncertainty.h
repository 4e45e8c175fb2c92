// Uncertainty and identifiability at a least-squares optimum, from the residual Jacobian.
//
// Contract:
// - J (m x n, row-major) is the Jacobian of the residuals r (cost = 0.5 |r|^2) with respect to n
//   variables in the units the user reads (physical parameters; nuisance variables such as initial
//   states may follow them). Variables flagged fixed (e.g. active bounds) are left out: their
//   covariance rows are zero and they are reported as fixed, not as estimated.
// - The columns are scaled to unit norm and the SVD of the scaled J is taken (of the R of its thin
//   QR when m > n); directions whose singular value is
//   below rank_tolerance times the largest, or below the Jacobian's own error
//   (UncertaintyOptions::jacobian_accuracy), cannot be determined from the data. Their variables
//   are reported unidentifiable (infinite standard error), with the combination of relative changes
//   that leaves the residuals unchanged, instead of a meaningless number.
// - Covariance = s^2 (J^T J)^+ on the determined directions, s^2 = 2 cost / (m - rank), the
// residual
//   variance (the noise scale when residuals are weighted by 1/sigma: s^2 ~ 1).
#pragma once

#include <Eigen/Core>
#include <Eigen/SparseCore>
#include <cstdint>
#include <string>
#include <vector>

#include "core/state.h"
#include "sysid/solve/row_triangle.h"  // RowTriangle (the compressed forms below)

namespace mjsysid {

// the two-sided 95 % quantile of the standard normal: a 95 % interval is value +- kZ95 std
inline constexpr double kZ95 = 1.959963984540054;

struct UncertaintyOptions {
  double rank_tolerance = 1e-7;  // relative singular value below which a direction is lost
  double participation = 0.1;    // |component| of a lost direction that makes a variable
                                 // unidentifiable
  bool scale_by_residual_variance = true;
  // relative accuracy of each Jacobian column (finite differences: ~h forward, ~h^2 central);
  // a singular value of the column-scaled J below jacobian_accuracy * sqrt(n free) cannot be told
  // from the Jacobian's own error and is lost too. 0: only rank_tolerance decides. Problem::Fit
  // sets it from FitOptions::jacobian.
  double jacobian_accuracy = 0;
};

struct Uncertainty {
  Eigen::MatrixXd covariance;       // n x n (zero rows for fixed and unidentifiable variables)
  Eigen::VectorXd std_error;        // n; +inf for unidentifiable, 0 for fixed
  std::vector<bool> identifiable;   // n
  Eigen::VectorXd singular_values;  // of the column-scaled J of the free variables, descending
  int rank = 0;
  double residual_variance = 0;             // s^2
  int dof = 0;                              // m - rank
  std::vector<std::string> unidentifiable;  // one line per lost direction
};

// names: n labels; values: n current values (for relative directions); fixed: n flags
Uncertainty AnalyzeUncertainty(const RowMatrix& J, double cost,
                               const std::vector<std::string>& names, const Eigen::VectorXd& values,
                               const std::vector<bool>& fixed,
                               const UncertaintyOptions& options = UncertaintyOptions());

// The same for the variables A (k x na, row-major: physical parameters, measurement terms) of a
// Jacobian [A B] whose further columns B (k x nb, sparse: multiple-shooting initial states,
// tangent space) are nuisance variables, without forming the k x (na + nb) matrix: B is
// eliminated by a sparse QR (the Schur complement of the state block) and the reduced Jacobian
// of A goes through AnalyzeUncertaintyCompressed. The k rows may stand for m >= k real rows (any
// rows with the real rows' [A B]^T [A B]: the compressed blocks' n + 1 rows each,
// sysid/solve/compressed_cost.h); m = k when they are the rows themselves. Equals the na x na block
// of AnalyzeUncertainty([A B]) over the real rows when B has full column rank; dof = m - rank(B) -
// rank(reduced A), s^2 = 2 cost / dof. Everything returned has size na (lost directions name
// variables of A only). Throws std::runtime_error when the QR fails.
Uncertainty AnalyzeUncertaintyReduced(const RowMatrix& A, const Eigen::SparseMatrix<double>& B,
                                      long long m, double cost,
                                      const std::vector<std::string>& names,
                                      const Eigen::VectorXd& values, const std::vector<bool>& fixed,
                                      const UncertaintyOptions& options = UncertaintyOptions());

// AnalyzeUncertainty of a Jacobian J with m rows given by a compressed equivalent R (any rows
// with R^T R = J^T J: a RowTriangle's R, sysid/mpi/'s compressed blocks): the same result as from
// J itself, with dof = m - rank and s^2 = 2 cost / dof over the m real rows.
Uncertainty AnalyzeUncertaintyCompressed(const RowMatrix& R, long long m, double cost,
                                         const std::vector<std::string>& names,
                                         const Eigen::VectorXd& values,
                                         const std::vector<bool>& fixed,
                                         const UncertaintyOptions& options = UncertaintyOptions());

}  // namespace mjsysid
