// the log-Cholesky inertial map: round trips, physical consistency for any variables, refusals,
// and the delta-method covariance against Monte Carlo
#include "core/inertia_cholesky.h"

#include <gtest/gtest.h>

#include <Eigen/Cholesky>
#include <Eigen/Core>
#include <algorithm>
#include <cmath>
#include <random>

namespace mjsysid {
namespace {

// a random body: variables drawn wide (mass 0.05-20 kg, lengths 0.05-2.7 m, products +-0.1 m)
void RandomTheta(std::mt19937_64& rng, double theta[kInertialVariables]) {
  std::uniform_real_distribution<double> log_range(-1.5, 1.5), offdiag(-0.1, 0.1);
  theta[0] = log_range(rng);
  for (int k = 1; k < 4; ++k) theta[k] = log_range(rng) - 1.5;
  for (int k = 4; k < 10; ++k) theta[k] = offdiag(rng);
}

// 1000 random variables: the body is physically consistent (mass > 0, moments > 0, strict
// triangle inequalities), its quaternion a unit one, and the variables read back within 1e-12
TEST(InertiaCholeskyTest, AnyVariablesAreAConsistentBodyAndRoundTrip) {
  std::mt19937_64 rng(3);
  for (int trial = 0; trial < 1000; ++trial) {
    double theta[kInertialVariables];
    RandomTheta(rng, theta);
    const BodyInertial b = FromLogCholesky(theta);
    ASSERT_GT(b.mass, 0);
    const double* i = b.inertia;
    ASSERT_GT(i[0], 0);
    EXPECT_LT(i[0], i[1] + i[2]);
    EXPECT_LT(i[1], i[0] + i[2]);
    EXPECT_LT(i[2], i[0] + i[1]);
    EXPECT_NEAR(std::hypot(std::hypot(b.quat[0], b.quat[1]), std::hypot(b.quat[2], b.quat[3])), 1.0,
                1e-14);
    double back[kInertialVariables];
    ASSERT_TRUE(ToLogCholesky(b, back));
    for (int k = 0; k < kInertialVariables; ++k) {
      EXPECT_NEAR(back[k], theta[k], 1e-12 * std::max(1.0, std::abs(theta[k])))
          << InertialVariableName(k) << ", trial " << trial;
    }
  }
}

// a point mass, a rod and a flat plate (moments on the triangle's edge) have no variables
TEST(InertiaCholeskyTest, NotStrictlyConsistentBodiesAreRefused) {
  double theta[kInertialVariables];
  BodyInertial b;
  b.mass = 1;
  for (const auto& moments : {Eigen::Vector3d(0, 0, 0), Eigen::Vector3d(0, 1, 1),
                              Eigen::Vector3d(1, 1, 2), Eigen::Vector3d(1, 1, 3)}) {
    for (int k = 0; k < 3; ++k) b.inertia[k] = moments[k];
    EXPECT_FALSE(ToLogCholesky(b, theta)) << moments.transpose();
  }
  b.mass = 0;
  b.inertia[0] = b.inertia[1] = b.inertia[2] = 1;
  EXPECT_FALSE(ToLogCholesky(b, theta)) << "zero mass";
}

// delta method against Monte Carlo: variables with standard errors 1% of their scale (alpha, d:
// 0.01; s, t: 1 mm), 20000 samples (seeded); every variance of mass, centre of mass and principal
// moments within 5% of the Monte Carlo one (its sampling error is 1%), covariances within 5% of the
// product of the standard deviations
TEST(InertiaCholeskyTest, DeltaMethodCovarianceMatchesMonteCarlo) {
  const double theta[kInertialVariables] = {0.2,   -1.2, -1.6, -2.0,  0.03,
                                            -0.02, 0.01, 0.1,  -0.05, 0.2};
  Eigen::Matrix<double, 10, 10, Eigen::RowMajor> c = Eigen::Matrix<double, 10, 10>::Zero();
  for (int k = 0; k < 10; ++k) c(k, k) = k < 4 ? 1e-4 : 1e-6;
  c(0, 1) = c(1, 0) = 0.5e-4;  // correlated alpha and d1
  Eigen::Matrix<double, 7, 7, Eigen::RowMajor> delta;
  PhysicalInertialCovariance(theta, c.data(), delta.data());

  const Eigen::LLT<Eigen::Matrix<double, 10, 10>> llt(c);
  const Eigen::Matrix<double, 10, 10> l = llt.matrixL();
  std::mt19937_64 rng(5);
  std::normal_distribution<double> n(0, 1);
  const int samples = 20000;
  Eigen::Matrix<double, 7, Eigen::Dynamic> y(7, samples);
  for (int s = 0; s < samples; ++s) {
    Eigen::Matrix<double, 10, 1> z;
    for (int k = 0; k < 10; ++k) z[k] = n(rng);
    Eigen::Matrix<double, 10, 1> t = l * z;
    for (int k = 0; k < 10; ++k) t[k] += theta[k];
    PhysicalInertial(t.data(), y.col(s).data(), nullptr);
  }
  const Eigen::Matrix<double, 7, 1> mean = y.rowwise().mean();
  const Eigen::Matrix<double, 7, Eigen::Dynamic> centred = y.colwise() - mean;
  const Eigen::Matrix<double, 7, 7> mc = centred * centred.transpose() / (samples - 1);
  for (int i = 0; i < 7; ++i) {
    EXPECT_NEAR(delta(i, i) / mc(i, i), 1.0, 0.05) << "variance " << i;
    for (int j = 0; j < i; ++j) {
      EXPECT_NEAR(delta(i, j), mc(i, j), 0.05 * std::sqrt(mc(i, i) * mc(j, j))) << i << "," << j;
    }
  }
}

}  // namespace
}  // namespace mjsysid
