// NRMSE and % fit (sysid/assess/metrics.h) on hand-made signals whose values are known in closed
// form.
#include "sysid/assess/metrics.h"

#include <gtest/gtest.h>

#include <cmath>
#include <string>
#include <vector>

namespace mjsysid {
namespace {

// y = sin over whole periods: mean 0, population std 1/sqrt(2)
Eigen::VectorXd Sine(int T) {
  Eigen::VectorXd y(T);
  for (int k = 0; k < T; ++k) y[k] = std::sin(2 * M_PI * k / T);
  return y;
}

TEST(Metrics, ChannelNamesIndexMultiColumnSensors) {
  SequenceResult s;
  s.sensor_names = {"angle", "accel", "touch"};
  s.sensor_dims = {1, 3, 1};
  EXPECT_EQ(ChannelNames(s),
            (std::vector<std::string>{"angle", "accel[0]", "accel[1]", "accel[2]", "touch"}));
}

TEST(Metrics, PerfectMatchIs100Percent) {
  const Eigen::VectorXd y = Sine(400);
  EXPECT_DOUBLE_EQ(Nrmse(y, y), 0.0);
  EXPECT_DOUBLE_EQ(FitPercent(Nrmse(y, y)), 100.0);
}

TEST(Metrics, TheMeanIsZeroPercentAndWorseIsNegative) {
  const Eigen::VectorXd y = Sine(400);
  const Eigen::VectorXd mean = Eigen::VectorXd::Constant(400, y.mean());
  EXPECT_NEAR(Nrmse(y, mean), 1.0, 1e-12);
  EXPECT_NEAR(FitPercent(Nrmse(y, mean)), 0.0, 1e-10);
  // the sign flipped: |y - (-y)| = 2 |y|, so NRMSE 2 and -100 %
  EXPECT_NEAR(Nrmse(y, -y), 2.0, 1e-12);
  EXPECT_NEAR(FitPercent(Nrmse(y, -y)), -100.0, 1e-9);
}

TEST(Metrics, ScaledSignal) {
  // yhat = 0.9 y: the error is 0.1 y, RMS(0.1 y) / std(y) = 0.1 (y has mean 0): 90 %
  const Eigen::VectorXd y = Sine(400);
  EXPECT_NEAR(Nrmse(y, 0.9 * y), 0.1, 1e-12);
  // an offset of c on a zero-mean signal of std 1/sqrt(2): NRMSE = c sqrt(2)
  const Eigen::VectorXd shifted = (y.array() + 0.05).matrix();
  EXPECT_NEAR(Nrmse(y, shifted), 0.05 * std::sqrt(2.0), 1e-12);
  // an offset in the measured data changes nothing (the measured mean is removed)
  const Eigen::VectorXd y_off = (y.array() + 3.0).matrix();
  EXPECT_NEAR(Nrmse(y_off, (0.9 * y).array() + 3.0), 0.1, 1e-12);
}

TEST(Metrics, ConstantMeasuredOrMismatchedLengthIsNaN) {
  const Eigen::VectorXd flat = Eigen::VectorXd::Constant(10, 2.0);
  EXPECT_TRUE(std::isnan(Nrmse(flat, flat)));
  EXPECT_TRUE(std::isnan(FitPercent(Nrmse(flat, flat))));
  EXPECT_TRUE(std::isnan(Nrmse(Sine(10), Sine(11))));
  EXPECT_TRUE(std::isnan(Nrmse(Eigen::VectorXd(), Eigen::VectorXd())));
}

// a measured cell that is NaN is not measured: the metric is over the others (issue 33: one NaN
// cell made a channel's % fit NaN); a NaN in the simulation at a measured cell stays NaN
TEST(Metrics, NotMeasuredCellsAreLeftOut) {
  const Eigen::VectorXd y = Sine(400);
  Eigen::VectorXd gappy = y;
  Eigen::VectorXd sim = 0.9 * y;
  gappy[17] = gappy[200] = std::nan("");
  sim[17] = 5.0;  // a simulated value where nothing was measured counts for nothing
  // over the 398 measured cells: the error is 0.1 y there, the spread that of y there
  Eigen::VectorXd ym(398), em(398);
  for (int k = 0, j = 0; k < 400; ++k) {
    if (k == 17 || k == 200) continue;
    ym[j] = y[k];
    em[j++] = 0.1 * y[k];
  }
  const double expected = em.norm() / (ym.array() - ym.mean()).matrix().norm();
  EXPECT_NEAR(Nrmse(gappy, sim), expected, 1e-14);
  EXPECT_NEAR(FitPercent(Nrmse(gappy, sim)), 90.0, 0.1);
  sim[30] = std::nan("");
  EXPECT_TRUE(std::isnan(Nrmse(gappy, sim)));
  EXPECT_TRUE(std::isnan(Nrmse(Eigen::VectorXd::Constant(5, std::nan("")), sim.head(5))));
}

TEST(Metrics, ChannelFitsNameColumnsAndCompareBothSimulations) {
  // two sensors: "a" (1-D) and "b" (2-D); initial 0.5 y, final 0.9 y
  const int T = 200;
  SequenceResult s;
  s.sensor_names = {"a", "b"};
  s.sensor_dims = {1, 2};
  s.time = Eigen::VectorXd::LinSpaced(T, 0, 1);
  s.measured.resize(T, 3);
  for (int c = 0; c < 3; ++c) s.measured.col(c) = (c + 1) * Sine(T);
  s.simulated_initial = 0.5 * s.measured;
  s.simulated_final = 0.9 * s.measured;
  s.simulated_final.col(2).setZero();  // b[1] not reproduced at all
  const std::vector<ChannelFit> f = ChannelFits(s);
  ASSERT_EQ(f.size(), 3u);
  EXPECT_EQ(f[0].channel, "a");
  EXPECT_EQ(f[1].channel, "b[0]");
  EXPECT_EQ(f[2].channel, "b[1]");
  for (int c = 0; c < 3; ++c) {
    EXPECT_NEAR(f[c].nrmse_initial, 0.5, 1e-12);
    EXPECT_NEAR(f[c].fit_initial, 50.0, 1e-9);
  }
  EXPECT_NEAR(f[0].fit_final, 90.0, 1e-9);
  EXPECT_NEAR(f[1].fit_final, 90.0, 1e-9);
  EXPECT_NEAR(f[2].fit_final, 0.0, 1e-9);

  // worst and median over the channels (NaN channels left out)
  const FitSummary fin = SummarizeFits(f, false);
  EXPECT_NEAR(fin.worst, 0.0, 1e-9);
  EXPECT_NEAR(fin.median, 90.0, 1e-9);
  const FitSummary ini = SummarizeFits(f, true);
  EXPECT_NEAR(ini.worst, 50.0, 1e-9);
  std::vector<ChannelFit> with_nan = f;
  with_nan.push_back(ChannelFit{"flat", NAN, NAN, NAN, NAN});
  EXPECT_NEAR(SummarizeFits(with_nan, false).median, 90.0, 1e-9);
  EXPECT_TRUE(std::isnan(SummarizeFits({}, false).worst));
}

}  // namespace
}  // namespace mjsysid
