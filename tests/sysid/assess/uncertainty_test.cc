#include "sysid/assess/uncertainty.h"

#include <gtest/gtest.h>

#include <Eigen/LU>
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <random>
#include <stdexcept>
#include <string>
#include <vector>

namespace mjsysid {
namespace {

// linear least squares y = a*t + b*t^2 with known noise: covariance = sigma^2 (J^T J)^-1
TEST(UncertaintyTest, LinearModelCovarianceMatchesClosedForm) {
  const int m = 200;
  RowMatrix J(m, 2);
  Eigen::VectorXd r(m);
  std::mt19937_64 rng(1);
  std::normal_distribution<double> n(0, 0.1);
  for (int i = 0; i < m; ++i) {
    const double t = 0.01 * i;
    J(i, 0) = t;
    J(i, 1) = t * t;
    r[i] = n(rng);
  }
  const double cost = 0.5 * r.squaredNorm();
  const Uncertainty u =
      AnalyzeUncertainty(J, cost, {"a", "b"}, Eigen::Vector2d(1.0, 2.0), {false, false});
  EXPECT_EQ(u.rank, 2);
  EXPECT_EQ(u.dof, m - 2);
  const double s2 = 2 * cost / (m - 2);
  EXPECT_NEAR(u.residual_variance, s2, 1e-15);
  const Eigen::MatrixXd expected = s2 * (J.transpose() * J).inverse();
  EXPECT_LE((u.covariance - expected).cwiseAbs().maxCoeff(), 1e-9 * expected.cwiseAbs().maxCoeff());
  EXPECT_NEAR(u.std_error[0], std::sqrt(expected(0, 0)), 1e-9 * std::sqrt(expected(0, 0)));
  EXPECT_TRUE(u.identifiable[0] && u.identifiable[1]);
  EXPECT_TRUE(u.unidentifiable.empty());
}

// two columns that only appear as a product direction: one lost direction naming both
TEST(UncertaintyTest, DependentColumnsAreReportedUnidentifiable) {
  RowMatrix J(50, 3);
  for (int i = 0; i < 50; ++i) {
    J(i, 0) = std::sin(0.1 * i);
    J(i, 1) = -2.0 * std::sin(0.1 * i);  // dependent on column 0
    J(i, 2) = std::cos(0.3 * i);
  }
  const Uncertainty u = AnalyzeUncertainty(J, 1.0, {"mass", "gear", "damping"},
                                           Eigen::Vector3d(1.0, 0.5, 0.1), {false, false, false});
  EXPECT_EQ(u.rank, 2);
  EXPECT_FALSE(u.identifiable[0]);
  EXPECT_FALSE(u.identifiable[1]);
  EXPECT_TRUE(u.identifiable[2]);
  EXPECT_TRUE(std::isinf(u.std_error[0]));
  EXPECT_TRUE(std::isfinite(u.std_error[2]));
  ASSERT_EQ(u.unidentifiable.size(), 1u);
  EXPECT_NE(u.unidentifiable[0].find("mass"), std::string::npos);
  EXPECT_NE(u.unidentifiable[0].find("gear"), std::string::npos);
  EXPECT_EQ(u.unidentifiable[0].find("damping"), std::string::npos);
}

TEST(UncertaintyTest, FixedAndZeroColumns) {
  RowMatrix J = RowMatrix::Zero(20, 3);
  for (int i = 0; i < 20; ++i) J(i, 0) = 1.0 + i, J(i, 2) = std::sin(i);
  const Uncertainty u =
      AnalyzeUncertainty(J, 0.5, {"a", "b", "c"}, Eigen::Vector3d(1, 1, 1), {false, false, true});
  EXPECT_TRUE(u.identifiable[0]);
  EXPECT_FALSE(u.identifiable[1]) << "a zero column has no effect";
  EXPECT_EQ(u.std_error[2], 0.0) << "a fixed variable is not estimated";
  ASSERT_EQ(u.unidentifiable.size(), 1u);
  EXPECT_NE(u.unidentifiable[0].find("no effect: b"), std::string::npos) << u.unidentifiable[0];
}

// A Jacobian with the structure of multiple shooting: na global columns in every row, nseg
// segments of `rows` rows, each with its own nx initial-state columns (entries 10 x normal draws)
// and (but the last) the next segment's nx columns in its last nx rows (continuity, -10 I); the
// global entries normal draws
RowMatrix MultipleShootingJacobian(int na, int nseg, int rows, int nx,
                                   std::normal_distribution<double>& n, std::mt19937_64& rng) {
  RowMatrix full = RowMatrix::Zero(nseg * rows, na + nseg * nx);
  for (int s = 0; s < nseg; ++s) {
    for (int k = 0; k < rows; ++k) {
      const int r = s * rows + k;
      for (int j = 0; j < na; ++j) full(r, j) = n(rng);
      for (int j = 0; j < nx; ++j) full(r, na + s * nx + j) = 10.0 * n(rng);
    }
    if (s + 1 < nseg) {
      for (int j = 0; j < nx; ++j) full(s * rows + rows - nx + j, na + (s + 1) * nx + j) = -10.0;
    }
  }
  return full;
}

// Schur elimination of nuisance columns (AnalyzeUncertaintyReduced) against the dense analysis of
// the whole Jacobian, on the structure of multiple shooting: 3 global columns in every row, 5
// segments of 40 rows, each with its own 2 initial-state columns and (but the last) the next
// segment's 2 columns in its last 2 rows (continuity, -w I). Entries: a fixed seed's normal
// draws. Tolerance: 1e-8 relative on covariance and standard errors.
TEST(UncertaintyTest, ReducedEqualsDenseOnMultipleShootingStructure) {
  const int na = 3, nseg = 5, rows = 40, nx = 2, m = nseg * rows, nb = nseg * nx;
  std::mt19937_64 rng(7);
  std::normal_distribution<double> n(0, 1);
  RowMatrix full = MultipleShootingJacobian(na, nseg, rows, nx, n, rng);
  double cost = 0;
  for (int r = 0; r < m; ++r) {
    const double e = 0.1 * n(rng);
    cost += 0.5 * e * e;
  }
  std::vector<std::string> names = {"a", "b", "c"};
  for (int j = 0; j < nb; ++j) names.push_back("x" + std::to_string(j));
  const Eigen::VectorXd values = Eigen::VectorXd::Ones(na + nb);
  const Uncertainty dense =
      AnalyzeUncertainty(full, cost, names, values, std::vector<bool>(na + nb, false));
  const RowMatrix A = full.leftCols(na);
  const Eigen::SparseMatrix<double> B = full.rightCols(nb).sparseView();
  const Uncertainty reduced = AnalyzeUncertaintyReduced(
      A, B, m, cost, {"a", "b", "c"}, Eigen::VectorXd::Ones(na), std::vector<bool>(na, false));
  EXPECT_EQ(dense.rank, na + nb);
  EXPECT_EQ(reduced.rank, na);
  EXPECT_EQ(reduced.dof, dense.dof);
  EXPECT_NEAR(reduced.residual_variance, dense.residual_variance, 1e-12 * dense.residual_variance);
  const Eigen::MatrixXd dense_cov = dense.covariance.topLeftCorner(na, na);
  EXPECT_LE((reduced.covariance - dense_cov).cwiseAbs().maxCoeff(),
            1e-8 * dense_cov.cwiseAbs().maxCoeff());
  for (int j = 0; j < na; ++j) {
    EXPECT_NEAR(reduced.std_error[j], dense.std_error[j], 1e-8 * dense.std_error[j]) << j;
    EXPECT_TRUE(reduced.identifiable[j]);
  }
}

// The same structure handed over compressed, as multiple shooting's compressed blocks are
// (sysid/solve/compressed_cost.h): each segment's rows [A_s B_s] (its 3 global and 4 state columns)
// replaced by their thin-QR triangle (RowTriangle, 7 rows instead of 40), the 200 real rows
// passed as m. Truth: the analysis of the 200 rows themselves. dof, rank and residual variance
// must be the rows' exactly (integers; the same cost), covariance and standard errors to 1e-10
// relative (a different QR of the same normal matrix: rounding only).
TEST(UncertaintyTest, ReducedOfCompressedRowsEqualsRows) {
  const int na = 3, nseg = 5, rows = 40, nx = 2, m = nseg * rows, nb = nseg * nx;
  std::mt19937_64 rng(11);
  std::normal_distribution<double> n(0, 1);
  RowMatrix full = MultipleShootingJacobian(na, nseg, rows, nx, n, rng);
  const double cost = 0.37;
  // per segment: the triangle of its rows over its own columns (globals, x_s, x_s+1), scattered
  // back into the full column space
  const int width = na + 2 * nx;
  RowMatrix packed = RowMatrix::Zero(nseg * width, na + nb);
  for (int s = 0; s < nseg; ++s) {
    const int own = s + 1 < nseg ? 2 * nx : nx;
    RowMatrix block(rows, na + own);
    block << full.block(s * rows, 0, rows, na), full.block(s * rows, na + s * nx, rows, own);
    RowTriangle tri(na + own);
    tri.Add(block);
    const Eigen::MatrixXd& R = tri.R();
    packed.block(s * width, 0, R.rows(), na) = R.leftCols(na);
    packed.block(s * width, na + s * nx, R.rows(), own) = R.rightCols(own);
  }
  const std::vector<std::string> names = {"a", "b", "c"};
  const Eigen::VectorXd values = Eigen::VectorXd::Ones(na);
  const std::vector<bool> fixed(na, false);
  const Uncertainty truth = AnalyzeUncertaintyReduced(
      full.leftCols(na), full.rightCols(nb).sparseView(), m, cost, names, values, fixed);
  const Uncertainty compressed = AnalyzeUncertaintyReduced(
      packed.leftCols(na), packed.rightCols(nb).sparseView(), m, cost, names, values, fixed);
  EXPECT_EQ(compressed.rank, truth.rank);
  EXPECT_EQ(compressed.dof, truth.dof);
  EXPECT_EQ(truth.dof, m - nb - na);
  EXPECT_EQ(compressed.residual_variance, truth.residual_variance);
  EXPECT_LE((compressed.covariance - truth.covariance).cwiseAbs().maxCoeff(),
            1e-10 * truth.covariance.cwiseAbs().maxCoeff());
  for (int j = 0; j < na; ++j) {
    EXPECT_NEAR(compressed.std_error[j], truth.std_error[j], 1e-10 * truth.std_error[j]) << j;
  }
}

// the rank decision follows the Jacobian's accuracy: columns a and b = a + 1e-5 * c (c orthogonal
// noise-like), 100 rows; the pair's small singular value of the column-scaled J is 2.2e-6
// (measured, printed). With jacobian_accuracy 0 (rank_tolerance 1e-7) the pair is kept; with 1e-5
// (a forward difference with step 1e-5) it is below the Jacobian's own error and reported
// unidentifiable
TEST(UncertaintyTest, RankToleranceFollowsJacobianAccuracy) {
  const int m = 100;
  RowMatrix J(m, 2);
  for (int i = 0; i < m; ++i) {
    J(i, 0) = std::sin(0.1 * i) + 2.0;
    J(i, 1) = J(i, 0) + 1e-5 * std::cos(0.37 * i);
  }
  const Uncertainty loose =
      AnalyzeUncertainty(J, 1.0, {"a", "b"}, Eigen::Vector2d(1, 1), {false, false});
  std::printf("[ measured ] singular values %.3g %.3g\n", loose.singular_values[0],
              loose.singular_values[1]);
  EXPECT_EQ(loose.rank, 2);
  UncertaintyOptions o;
  o.jacobian_accuracy = 1e-5;
  const Uncertainty strict =
      AnalyzeUncertainty(J, 1.0, {"a", "b"}, Eigen::Vector2d(1, 1), {false, false}, o);
  EXPECT_EQ(strict.rank, 1);
  EXPECT_FALSE(strict.identifiable[0]);
  EXPECT_FALSE(strict.identifiable[1]);
}

// the triangle of rows added in uneven blocks (3000 rows in 7 blocks, chunks of 1024 inside) has
// the normal matrix of the stacked rows, and blocks given in one call or several give the same
// bits (the chunks follow the rows, not the calls). Truth: J^T J of 3000 random rows (seed 3),
// 4 columns; tolerance 1e-12 relative (rounding of a QR of well-conditioned columns)
TEST(RowTriangleTest, NormalMatrixOfAllRowsWhateverTheBlocks) {
  const int m = 3000, n = 4;
  std::mt19937_64 rng(3);
  std::normal_distribution<double> g(0, 1);
  RowMatrix J(m, n);
  for (int i = 0; i < m; ++i) {
    for (int j = 0; j < n; ++j) J(i, j) = g(rng) * (j + 1);
  }
  RowTriangle blocks(n), whole(n), again(n);
  const int cuts[] = {0, 1, 700, 1024, 1030, 2049, 2999, m};
  for (int b = 0; b + 1 < 8; ++b) blocks.Add(J.middleRows(cuts[b], cuts[b + 1] - cuts[b]));
  whole.Add(J);
  for (int first = 0; first < m; first += RowTriangle::kChunkRows) {
    again.Add(J.middleRows(first, std::min(RowTriangle::kChunkRows, m - first)));
  }
  EXPECT_EQ(blocks.rows(), m);
  ASSERT_EQ(blocks.R().rows(), n);
  const Eigen::MatrixXd JtJ = J.transpose() * J;
  const Eigen::MatrixXd RtR = blocks.R().transpose() * blocks.R();
  EXPECT_LE((RtR - JtJ).cwiseAbs().maxCoeff(), 1e-12 * JtJ.cwiseAbs().maxCoeff());
  EXPECT_TRUE((whole.R().array() == again.R().array()).all());
  for (int i = 0; i < n; ++i) {
    for (int j = 0; j < i; ++j) EXPECT_EQ(blocks.R()(i, j), 0.0);
  }
  // fewer rows than columns: a trapezoid of the rows seen
  RowTriangle short_rows(n);
  short_rows.Add(J.topRows(2));
  EXPECT_EQ(short_rows.R().rows(), 2);
  EXPECT_THROW(short_rows.Add(RowMatrix::Zero(1, n + 1)), std::invalid_argument);
}

// the uncertainty from the triangle of [J r] equals the one from J itself: the linear model of
// LinearModelCovarianceMatchesClosedForm plus a third, nuisance column, 500 rows, noise 0.1
// (seed 5); one variable fixed. Tolerance 1e-9 relative on covariance and standard errors (two
// QR paths of the same columns); rank, dof and s^2 exact
TEST(UncertaintyTest, CompressedEqualsFullJacobian) {
  const int m = 500, n = 3;
  std::mt19937_64 rng(5);
  std::normal_distribution<double> g(0, 0.1);
  RowMatrix Jr(m, n + 1);
  for (int i = 0; i < m; ++i) {
    const double t = 0.01 * i;
    Jr.row(i) << t, t * t, std::cos(t), g(rng);
  }
  const RowMatrix J = Jr.leftCols(n);
  const double cost = 0.5 * Jr.col(n).squaredNorm();
  const Eigen::VectorXd values = Eigen::Vector3d(1.0, 2.0, 3.0);
  RowTriangle tri(n + 1);
  tri.Add(Jr);
  const RowMatrix R = tri.R().leftCols(n);
  for (const std::vector<bool>& fixed :
       {std::vector<bool>{false, false, false}, std::vector<bool>{false, true, false}}) {
    const Uncertainty full = AnalyzeUncertainty(J, cost, {"a", "b", "c"}, values, fixed);
    const Uncertainty compressed =
        AnalyzeUncertaintyCompressed(R, m, cost, {"a", "b", "c"}, values, fixed);
    EXPECT_EQ(compressed.rank, full.rank);
    EXPECT_EQ(compressed.dof, full.dof);
    EXPECT_EQ(compressed.residual_variance, full.residual_variance);
    EXPECT_LE((compressed.covariance - full.covariance).cwiseAbs().maxCoeff(),
              1e-9 * full.covariance.cwiseAbs().maxCoeff());
    for (int j = 0; j < n; ++j) {
      EXPECT_NEAR(compressed.std_error[j], full.std_error[j], 1e-9 * full.std_error[j]) << j;
    }
    // the triangle's last column holds the residuals' quadratic form: |q|^2 + rho^2 = |r|^2
    EXPECT_NEAR(0.5 * tri.R().col(n).squaredNorm(), cost, 1e-12 * cost);
  }
}

}  // namespace
}  // namespace mjsysid
