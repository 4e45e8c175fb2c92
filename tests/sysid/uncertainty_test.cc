#include "sysid/uncertainty.h"

#include <gtest/gtest.h>

#include <Eigen/LU>
#include <cmath>
#include <random>

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

}  // namespace
}  // namespace mjsysid
