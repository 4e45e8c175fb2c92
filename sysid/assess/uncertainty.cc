#include "sysid/assess/uncertainty.h"

#include <Eigen/QR>
#include <Eigen/SPQRSupport>
#include <Eigen/SVD>
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <stdexcept>
#include <string>

namespace mjsysid {
namespace {

// standard errors from the covariance: 0 for fixed, +inf for unidentifiable variables
void SetStdErrors(const std::vector<bool>& fixed, Uncertainty* u) {
  for (Eigen::Index j = 0; j < u->std_error.size(); ++j) {
    u->std_error[j] = fixed[j]             ? 0.0
                      : u->identifiable[j] ? std::sqrt(std::max(u->covariance(j, j), 0.0))
                                           : std::numeric_limits<double>::infinity();
  }
}

}  // namespace

Uncertainty AnalyzeUncertainty(const RowMatrix& J, double cost,
                               const std::vector<std::string>& names, const Eigen::VectorXd& values,
                               const std::vector<bool>& fixed, const UncertaintyOptions& options) {
  const int m = static_cast<int>(J.rows()), n = static_cast<int>(J.cols());
  Uncertainty u;
  u.covariance.setZero(n, n);
  u.std_error.setZero(n);
  u.identifiable.assign(n, true);

  // free variables, with their column norms
  std::vector<int> free;
  for (int j = 0; j < n; ++j) {
    if (!fixed[j]) free.push_back(j);
  }
  const int nf = static_cast<int>(free.size());
  if (nf == 0) return u;
  Eigen::VectorXd D(nf);
  for (int a = 0; a < nf; ++a) D[a] = J.col(free[a]).norm();

  // SVD of the column-scaled Jacobian (a zero column stays zero: lost direction), through the
  // R of its thin QR when it has more rows than columns (same singular values and V, nf x nf)
  RowMatrix Js(m, nf);
  for (int a = 0; a < nf; ++a) Js.col(a) = J.col(free[a]) / (D[a] > 0 ? D[a] : 1.0);
  Eigen::MatrixXd R;
  if (m > nf) {
    Eigen::HouseholderQR<Eigen::MatrixXd> qr(Js);
    R = qr.matrixQR().topRows(nf).triangularView<Eigen::Upper>();
  } else {
    R = Js;
  }
  const Eigen::JacobiSVD<Eigen::MatrixXd> svd(R, Eigen::ComputeFullV);
  // descending singular values, padded with zeros when there are fewer rows than variables
  u.singular_values = Eigen::VectorXd::Zero(nf);
  u.singular_values.head(svd.singularValues().size()) = svd.singularValues();
  const Eigen::MatrixXd& V = svd.matrixV();
  const Eigen::VectorXd lambda = u.singular_values.array().square();
  const double smax = u.singular_values.size() ? u.singular_values[0] : 0.0;
  // the rank decision: relative to the largest singular value, and above the Jacobian's error
  const double threshold = std::max(options.rank_tolerance * smax,
                                    options.jacobian_accuracy * std::sqrt(static_cast<double>(nf)));
  std::vector<bool> kept(nf, false);
  for (int i = 0; i < nf; ++i) {
    kept[i] = smax > 0 && u.singular_values[i] > threshold;
    u.rank += kept[i] ? 1 : 0;
  }
  u.dof = m - u.rank;
  u.residual_variance = u.dof > 0 ? 2.0 * cost / u.dof : std::numeric_limits<double>::quiet_NaN();
  const double s2 = options.scale_by_residual_variance ? u.residual_variance : 1.0;

  // lost directions: the variables taking part cannot be told apart
  for (int i = 0; i < nf; ++i) {
    if (kept[i]) continue;
    // relative change of each variable along the direction: v_a / (D_a |p_a|)
    Eigen::VectorXd rel(nf);
    for (int a = 0; a < nf; ++a) {
      const double scale = (D[a] > 0 ? D[a] : 1.0) * std::max(std::abs(values[free[a]]), 1e-12);
      rel[a] = V(a, i) / scale;
    }
    // scale to a largest entry of +1 (the sign of an eigenvector is arbitrary)
    Eigen::Index big = 0;
    rel.cwiseAbs().maxCoeff(&big);
    rel /= rel[big] != 0 ? rel[big] : 1.0;
    std::string line;
    int members = 0;
    for (int a = 0; a < nf; ++a) {
      if (std::abs(V(a, i)) < options.participation) continue;
      u.identifiable[free[a]] = false;
      char buf[64];
      std::snprintf(buf, sizeof(buf), "%+.3g", rel[a]);
      line += (members++ ? ", " : "") + names[free[a]] + " " + buf;
    }
    char head[96];
    std::snprintf(head, sizeof(head), "singular value %.3g (relative %.2g): ", u.singular_values[i],
                  smax > 0 ? u.singular_values[i] / smax : 0.0);
    u.unidentifiable.push_back(
        std::string(head) + (members == 1 ? "no effect: " : "") + line +
        (members > 1 ? " (relative changes that leave the fit unchanged)" : ""));
  }

  // covariance on the kept directions, back in the variables' units
  Eigen::MatrixXd Cn = Eigen::MatrixXd::Zero(nf, nf);
  for (int i = 0; i < nf; ++i) {
    if (kept[i]) Cn += V.col(i) * V.col(i).transpose() / lambda[i];
  }
  for (int a = 0; a < nf; ++a) {
    for (int b = 0; b < nf; ++b) {
      const double da = D[a] > 0 ? D[a] : 1.0, db = D[b] > 0 ? D[b] : 1.0;
      u.covariance(free[a], free[b]) = s2 * Cn(a, b) / (da * db);
    }
  }
  SetStdErrors(fixed, &u);
  return u;
}

Uncertainty AnalyzeUncertaintyReduced(const RowMatrix& A, const Eigen::SparseMatrix<double>& B,
                                      long long m, double cost,
                                      const std::vector<std::string>& names,
                                      const Eigen::VectorXd& values, const std::vector<bool>& fixed,
                                      const UncertaintyOptions& options) {
  if (B.cols() == 0) {
    return AnalyzeUncertaintyCompressed(A, m, cost, names, values, fixed, options);
  }
  const Eigen::Index k = A.rows();
  // nuisance columns scaled to unit norm (a zero column stays zero and drops out of the rank)
  Eigen::VectorXd scale = Eigen::VectorXd::Ones(B.cols());
  for (Eigen::Index c = 0; c < B.cols(); ++c) {
    const double norm = B.col(c).norm();
    if (norm > 0) scale[c] = 1.0 / norm;
  }
  Eigen::SparseMatrix<double> Bs = B * scale.asDiagonal();
  Bs.makeCompressed();
  // sparse QR of the nuisance columns: B P = Q [R; 0]. The last k - rank(B) rows of Q^T A are A
  // projected onto the complement of B's range, the Jacobian of the reduced problem (the Schur
  // complement A^T A - A^T B (B^T B)^+ B^T A is its normal matrix)
  // (SuiteSparseQR, multifrontal: the arm5 experiment's factorisation took 9 % of its 1-thread fit
  // with Eigen's left-looking SparseQR, serial time that a second thread does not shorten)
  Eigen::SPQR<Eigen::SparseMatrix<double>> qr(Bs);
  if (qr.info() != Eigen::Success) {
    throw std::runtime_error("uncertainty: sparse QR of the initial-state columns failed");
  }
  const Eigen::Index rank_b = qr.rank();
  Eigen::MatrixXd QtA = qr.matrixQ().transpose() * Eigen::MatrixXd(A);
  const RowMatrix reduced = QtA.bottomRows(k - rank_b);
  // its normal matrix is the real rows' Schur complement; the dof counts the m - rank(B) real
  // rows left after the elimination
  return AnalyzeUncertaintyCompressed(reduced, m - rank_b, cost, names, values, fixed, options);
}

Uncertainty AnalyzeUncertaintyCompressed(const RowMatrix& R, long long m, double cost,
                                         const std::vector<std::string>& names,
                                         const Eigen::VectorXd& values,
                                         const std::vector<bool>& fixed,
                                         const UncertaintyOptions& options) {
  // the analysis of R at s^2 = 1, then the residual variance over the m real rows
  UncertaintyOptions unscaled = options;
  unscaled.scale_by_residual_variance = false;
  Uncertainty u = AnalyzeUncertainty(R, cost, names, values, fixed, unscaled);
  const long long dof = m - u.rank;
  u.dof = static_cast<int>(dof);
  u.residual_variance =
      dof > 0 ? 2.0 * cost / static_cast<double>(dof) : std::numeric_limits<double>::quiet_NaN();
  if (options.scale_by_residual_variance) {
    u.covariance *= u.residual_variance;
    SetStdErrors(fixed, &u);
  }
  return u;
}

}  // namespace mjsysid
