// Residual diagnostics (sysid/assess/residual_diagnostics.h) on residuals whose statistics are
// known: white Gaussian noise, AR(1) noise (correlation time (1 + phi) / (1 - phi)), an offset,
// NaN cells and sequences too short to tell.
#include "sysid/assess/residual_diagnostics.h"

#include <gtest/gtest.h>

#include <cmath>
#include <random>
#include <vector>

namespace mjsysid {
namespace {

// n samples of AR(1) noise with marginal std sigma (phi 0: white)
Eigen::VectorXd Ar1(int n, double phi, double sigma, unsigned seed) {
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> w(0, 1);
  Eigen::VectorXd e(n);
  double x = sigma * w(rng);
  for (int k = 0; k < n; ++k) {
    e[k] = x;
    x = phi * x + std::sqrt(1 - phi * phi) * sigma * w(rng);
  }
  return e;
}

TEST(ResidualDiagnostics, WhiteNoiseIsWhiteWithCorrelationTimeOne) {
  // 2 sequences x 3000 samples of N(0, 0.01^2), stated sigma 0.01
  int white = 0;
  for (unsigned seed = 1; seed <= 20; ++seed) {
    const ResidualDiagnostics d = DiagnoseResiduals(
        "angle", {Ar1(3000, 0, 0.01, seed), Ar1(3000, 0, 0.01, seed + 100)}, 0.01);
    EXPECT_EQ(d.samples, 6000);
    EXPECT_NEAR(d.ratio, 1.0, 0.05);
    EXPECT_NEAR(d.rms, 0.01, 5e-4);
    EXPECT_NEAR(d.lag1, 0.0, 0.06);
    EXPECT_NEAR(d.tau, 1.0, 0.3);
    EXPECT_LT(d.bias_units, 4.0);
    white += d.white;
  }
  // the portmanteau test at 1e-3: 20 of 20 white (a false alarm every 1000 fits)
  EXPECT_EQ(white, 20);
}

TEST(ResidualDiagnostics, FilteredNoiseIsNotWhiteAndItsCorrelationTimeIsMeasured) {
  // AR(1) with phi 0.9: tau = 1.9 / 0.1 = 19 samples, lag-1 correlation 0.9
  for (unsigned seed = 1; seed <= 10; ++seed) {
    const ResidualDiagnostics d =
        DiagnoseResiduals("rate", {Ar1(20000, 0.9, 0.01, seed)}, std::nan(""));
    EXPECT_FALSE(d.white);
    EXPECT_LT(d.portmanteau_p, 1e-10);
    EXPECT_NEAR(d.lag1, 0.9, 0.02);
    EXPECT_NEAR(d.tau, 19.0, 0.2 * 19.0) << "seed " << seed;
    EXPECT_TRUE(std::isnan(d.ratio));
    EXPECT_FALSE(ResidualSentence(d).empty());
  }
}

TEST(ResidualDiagnostics, AnOffsetIsABias) {
  // white noise 0.01 plus 0.002: over 5000 samples the mean's standard error is 1.4e-4, so the
  // offset is ~14 standard errors
  Eigen::VectorXd e = Ar1(5000, 0, 0.01, 7);
  e.array() += 0.002;
  const ResidualDiagnostics d = DiagnoseResiduals("x", {e}, 0.01);
  EXPECT_NEAR(d.mean, 0.002, 5e-4);
  EXPECT_GT(d.bias_units, 8.0);
  EXPECT_TRUE(d.white);
  EXPECT_NE(ResidualSentence(d).find("biased"), std::string::npos);
}

TEST(ResidualDiagnostics, NotMeasuredCellsAreSkippedAndShortChannelsCannotTell) {
  Eigen::VectorXd e = Ar1(1000, 0, 0.01, 3);
  for (int k = 0; k < 1000; k += 10) e[k] = std::nan("");
  const ResidualDiagnostics d = DiagnoseResiduals("x", {e}, 0.01);
  EXPECT_EQ(d.samples, 900);
  EXPECT_TRUE(std::isfinite(d.tau));
  EXPECT_TRUE(d.white);
  // fewer than 4 x 20 samples: no correlation figures, counted white
  const ResidualDiagnostics s = DiagnoseResiduals("x", {Ar1(50, 0.9, 0.01, 3)}, 0.01);
  EXPECT_EQ(s.samples, 50);
  EXPECT_TRUE(std::isnan(s.tau));
  EXPECT_TRUE(s.white);
  EXPECT_TRUE(ResidualSentence(s).empty());
  // nothing measured
  const ResidualDiagnostics none =
      DiagnoseResiduals("x", {Eigen::VectorXd::Constant(100, std::nan(""))}, 0.01);
  EXPECT_EQ(none.samples, 0);
  EXPECT_TRUE(std::isnan(none.rms));
}

TEST(ResidualDiagnostics, TheInflationIsTheLargestCorrelationTimeOfTheChannelsNotWhite) {
  const std::vector<ResidualDiagnostics> ds = {
      DiagnoseResiduals("a", {Ar1(20000, 0, 0.01, 1)}, 0.01),
      DiagnoseResiduals("b", {Ar1(20000, 0.8, 0.01, 2)}, 0.01),
      DiagnoseResiduals("c", {Ar1(20000, 0.9, 0.01, 3)}, 0.01)};
  std::string channel;
  EXPECT_EQ(CorrelationInflation(ds, &channel), ds[2].tau);
  EXPECT_EQ(channel, "c");
  EXPECT_EQ(CorrelationInflation({ds[0]}, &channel), 1.0);
  EXPECT_EQ(channel, "");
}

// AR(1) noise has rho(k) = phi^k; the lag-1 value is DiagnoseResiduals' own; NaN cells are left out
// of the pairs; constant residuals have no autocorrelation
TEST(ResidualDiagnostics, TheAutocorrelationOfAr1NoiseIsPhiToTheLag) {
  const std::vector<Eigen::VectorXd> e = {Ar1(20000, 0.8, 0.01, 3), Ar1(20000, 0.8, 0.01, 4)};
  const Eigen::VectorXd rho = ResidualAutocorrelation(e, 5);
  ASSERT_EQ(rho.size(), 6);
  EXPECT_DOUBLE_EQ(rho[0], 1.0);
  for (int k = 1; k <= 5; ++k) EXPECT_NEAR(rho[k], std::pow(0.8, k), 0.03) << "lag " << k;
  EXPECT_DOUBLE_EQ(rho[1], DiagnoseResiduals("x", e, 0.01).lag1);

  std::vector<Eigen::VectorXd> gappy = e;
  gappy[0][100] = std::nan("");
  EXPECT_TRUE(ResidualAutocorrelation(gappy, 3).allFinite());
  EXPECT_TRUE(ResidualAutocorrelation({Eigen::VectorXd::Constant(50, 0.2)}, 3).hasNaN());
  EXPECT_TRUE(ResidualAutocorrelation({Eigen::VectorXd::Constant(1, 0.2)}, 3).hasNaN());
}

// the residual columns pooled by channel over sequences, multi-column sensors as "name[i]"
TEST(ResidualDiagnostics, ResidualsArePooledByChannelName) {
  SequenceResult a, b;
  for (SequenceResult* s : {&a, &b}) {
    s->sensor_names = {"angle", "accel"};
    s->sensor_dims = {1, 3};
    s->measured = RowMatrix::Zero(4, 4);
    s->simulated_final = RowMatrix::Ones(4, 4);
  }
  b.sensor_names = {"accel", "angle"};
  b.sensor_dims = {3, 1};
  const std::vector<ChannelResiduals> pooled = PoolResidualsByChannel({a, b});
  ASSERT_EQ(pooled.size(), 4u);
  EXPECT_EQ(pooled[0].channel, "angle");
  EXPECT_EQ(pooled[1].channel, "accel[0]");
  EXPECT_EQ(pooled[3].channel, "accel[2]");
  EXPECT_EQ(pooled[3].sensor, "accel");
  for (const ChannelResiduals& c : pooled) {
    ASSERT_EQ(c.columns.size(), 2u) << c.channel;
    EXPECT_DOUBLE_EQ(c.columns[1].sum(), 4.0);
  }
}

TEST(ResidualDiagnostics, Chi2SurvivalMatchesKnownQuantiles) {
  // chi-square with 20 dof: P(X > 31.41) = 0.05, P(X > 45.31) = 0.001
  EXPECT_NEAR(Chi2Survival(31.41, 20), 0.05, 0.003);
  EXPECT_NEAR(Chi2Survival(45.31, 20), 0.001, 2e-4);
  EXPECT_EQ(Chi2Survival(0, 20), 1.0);
}

}  // namespace
}  // namespace mjsysid
