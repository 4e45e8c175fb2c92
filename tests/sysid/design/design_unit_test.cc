// The excitation design's parts on their own: the Fourier family (peak, smooth start and end,
// coefficient layout), the Fisher information against a plain computation, the criteria, and
// CMA-ES on a function whose minimum is known.
#include <gtest/gtest.h>

#include <Eigen/Dense>
#include <cmath>
#include <limits>
#include <random>

#include "sysid/design/cma_es.h"
#include "sysid/design/fourier.h"
#include "sysid/design/information.h"

namespace mjsysid::design {
namespace {

// 3 actuators, 4 harmonics of 0.5 Hz, 1 s ramps over 6 s at 2 ms
TEST(FourierShapesTest, PeakIsOneAndTheWindowStartsAndEndsAtRest) {
  FourierBasis b;
  b.base_frequency = 0.5;
  b.harmonics = 4;
  b.ramp = 1.0;
  const int nu = 3, steps = 3001;
  const double dt = 0.002;
  std::mt19937_64 rng(7);
  std::normal_distribution<double> normal;
  Eigen::VectorXd c(nu * CoefficientsPerActuator(b));
  for (Eigen::Index i = 0; i < c.size(); ++i) c[i] = normal(rng);
  const RowMatrix g = FourierShapes(b, c, nu, steps, dt);
  ASSERT_EQ(g.rows(), steps);
  ASSERT_EQ(g.cols(), nu);
  for (int i = 0; i < nu; ++i) {
    EXPECT_DOUBLE_EQ(g.col(i).cwiseAbs().maxCoeff(), 1.0) << i;
    EXPECT_EQ(g(0, i), 0.0);
    EXPECT_EQ(g(steps - 1, i), 0.0);
    // a raised cosine: value and slope ~0 next to both ends (second order in t)
    EXPECT_LT(std::abs(g(1, i)), 1e-4);
    EXPECT_LT(std::abs(g(steps - 2, i)), 1e-4);
  }
  // a multiple of the coefficients gives the same shapes
  EXPECT_TRUE(FourierShapes(b, 3.5 * c, nu, steps, dt).isApprox(g, 1e-14));
  // controls: centre + scale * amplitude * shape
  const RowMatrix u =
      DesignControls(g, Eigen::Vector3d(0.1, 0, -1), Eigen::Vector3d(2, 1, 0.5), 0.7);
  EXPECT_NEAR((u.col(0).array() - 0.1).abs().maxCoeff(), 1.4, 1e-14);
  EXPECT_NEAR((u.col(2).array() + 1).abs().maxCoeff(), 0.35, 1e-14);
}

// the layout: actuator i's a_1..a_H then b_0..b_H; only b_0 of actuator 1 set gives the window
TEST(FourierShapesTest, CoefficientLayoutPutsTheConstantAfterTheSines) {
  FourierBasis b;
  b.base_frequency = 1;
  b.harmonics = 2;
  b.ramp = 0.1;
  Eigen::VectorXd c = Eigen::VectorXd::Zero(2 * 5);
  c[5 + 2] = 1;  // actuator 1, b_0
  const RowMatrix g = FourierShapes(b, c, 2, 1001, 0.001);
  EXPECT_TRUE(g.col(0).isZero());
  for (int k = 0; k < 1001; ++k) EXPECT_NEAR(g(k, 1), Window(k * 0.001, 1.0, 0.1), 1e-12);
  c.setZero();
  c[1] = 1;  // actuator 0, a_2: sin(2 pi 2 t) under the window
  const RowMatrix s = FourierShapes(b, c, 2, 1001, 0.001);
  EXPECT_NEAR(s(375, 0), std::sin(2 * M_PI * 2 * 0.375) / 1.0, 1e-12);
}

TEST(FourierShapesTest, BadSizesThrow) {
  FourierBasis b;
  EXPECT_THROW(FourierShapes(b, Eigen::VectorXd::Zero(3), 1, 100, 0.1), std::invalid_argument);
  b.harmonics = 1;
  b.ramp = 6;  // longer than half of 9.9 s
  EXPECT_THROW(FourierShapes(b, Eigen::VectorXd::Zero(3), 1, 100, 0.1), std::invalid_argument);
}

// F = sum_k J_k^T W J_k + P against a plain product; std = sqrt(diag(F^-1)); relative std and
// criteria from R = D F D
TEST(InformationTest, FisherAndStandardErrorsMatchAPlainComputation) {
  const int T = 50, ns = 3, np = 2;
  std::mt19937_64 rng(3);
  std::normal_distribution<double> normal;
  Sensitivity s;
  s.DyDp.resize(T * ns, np);
  for (Eigen::Index i = 0; i < s.DyDp.size(); ++i) s.DyDp.data()[i] = normal(rng);
  SensorWeights w{{0, 2}, {0.1, 0.5}};  // column 1 not fitted
  const Eigen::Vector2d values(2.0, -0.5), prior(0.0, 4.0);
  const Information info = InformationOf({s}, ns, w, values, prior);
  Eigen::MatrixXd F = prior.asDiagonal();
  for (int k = 0; k < T; ++k) {
    F += s.DyDp.row(k * ns).transpose() * s.DyDp.row(k * ns) / 0.01;
    F += s.DyDp.row(k * ns + 2).transpose() * s.DyDp.row(k * ns + 2) / 0.25;
  }
  EXPECT_TRUE(info.fisher.isApprox(F, 1e-12));
  const Eigen::MatrixXd C = F.inverse();
  for (int j = 0; j < np; ++j) {
    EXPECT_NEAR(info.std[j], std::sqrt(C(j, j)), 1e-12 * std::sqrt(C(j, j)));
    EXPECT_NEAR(info.relative_std[j], info.std[j] / std::abs(values[j]), 1e-15);
  }
  const Eigen::MatrixXd R = values.cwiseAbs().asDiagonal() * F * values.cwiseAbs().asDiagonal();
  EXPECT_NEAR(info.log_det, std::log(R.determinant()), 1e-10);
  EXPECT_NEAR(CriterionValue(info, DesignCriterion::kDOptimal), -info.log_det, 0);
  EXPECT_EQ(CriterionValue(info, DesignCriterion::kWorstRelativeStd), info.relative_std.maxCoeff());
  const Eigen::VectorXd lambda = Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd>(R).eigenvalues();
  EXPECT_NEAR(info.condition, lambda[1] / lambda[0], 1e-9 * info.condition);
  // the search's smooth stand-in bounds the worst from above within np^(1/8)
  const double score = SearchScore(info, DesignCriterion::kWorstRelativeStd);
  EXPECT_GE(score, info.worst_relative_std);
  EXPECT_LE(score, info.worst_relative_std * std::pow(2.0, 1.0 / 8) * (1 + 1e-12));
}

// a parameter no sensor sees: singular, infinite standard errors and criteria
TEST(InformationTest, AParameterTheSensorsDoNotSeeIsInfinitelyUncertain) {
  Sensitivity s;
  s.DyDp = RowMatrix::Zero(20, 2);
  s.DyDp.col(0).setOnes();
  const Information info = InformationOf({s}, 1, SensorWeights{{0}, {1.0}}, Eigen::Vector2d(1, 1),
                                         Eigen::Vector2d::Zero());
  EXPECT_TRUE(std::isinf(info.std[1]));
  EXPECT_TRUE(std::isinf(info.worst_relative_std));
  EXPECT_EQ(info.log_det, -std::numeric_limits<double>::infinity());
  EXPECT_TRUE(std::isinf(CriterionValue(info, DesignCriterion::kDOptimal)));
  EXPECT_TRUE(std::isinf(CriterionValue(info, DesignCriterion::kConditionNumber)));
}

TEST(InformationTest, CriterionNamesRoundTrip) {
  for (DesignCriterion c : {DesignCriterion::kDOptimal, DesignCriterion::kWorstRelativeStd,
                            DesignCriterion::kConditionNumber}) {
    DesignCriterion back = DesignCriterion::kDOptimal;
    EXPECT_TRUE(ParseCriterion(CriterionName(c), &back));
    EXPECT_EQ(back, c);
  }
  DesignCriterion out;
  EXPECT_FALSE(ParseCriterion("a_optimal", &out));
}

// an ill-conditioned ellipsoid in 10 dimensions (axes 1 .. 1e3) from a start 3 away: CMA-ES
// finds the minimum at (1, ..., 1) to 1e-6 within 600 generations, and the same seed gives the
// same path
TEST(CmaEsTest, MinimisesAnIllConditionedEllipsoid) {
  const int n = 10;
  const auto f = [n](const Eigen::VectorXd& x) {
    double v = 0;
    for (int i = 0; i < n; ++i) v += std::pow(1e3, 2.0 * i / (n - 1)) * std::pow(x[i] - 1, 2);
    return v;
  };
  const auto run = [&](int generations) {
    CmaEs es(Eigen::VectorXd::Constant(n, -2), 1.0, 11);
    double best = std::numeric_limits<double>::infinity();
    for (int g = 0; g < generations; ++g) {
      std::vector<double> scores;
      for (const Eigen::VectorXd& x : es.Ask()) {
        scores.push_back(f(x));
        best = std::min(best, scores.back());
      }
      es.Tell(scores);
    }
    return std::make_pair(best, es.mean());
  };
  const auto [best, mean] = run(600);
  EXPECT_LT(best, 1e-6);
  EXPECT_LT((mean - Eigen::VectorXd::Ones(n)).norm(), 1e-3);
  EXPECT_EQ(run(600).second, mean);
  CmaEs es(Eigen::VectorXd::Zero(n), 1.0, 1);
  es.Ask();
  EXPECT_THROW(es.Tell({1.0}), std::invalid_argument);
}

}  // namespace
}  // namespace mjsysid::design
