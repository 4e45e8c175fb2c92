// EstimateNoiseStd (sysid/assess/noise_estimate.h): the noise of a logged column from the log
// alone, on signals with a stated noise.
#include "sysid/assess/noise_estimate.h"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <limits>
#include <random>

namespace mjsysid {
namespace {

// a 0.7 Hz sine of amplitude 1 sampled at 1 kHz (5000 samples) plus white Gaussian noise sigma
Eigen::VectorXd NoisySine(double sigma, int seed) {
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> noise(0, sigma);
  Eigen::VectorXd y(5000);
  for (int k = 0; k < y.size(); ++k) y[k] = std::sin(2 * M_PI * 0.7 * k * 1e-3) + noise(rng);
  return y;
}

// white noise 0.01 on a smooth sine: the estimate is within 10 % of 0.01 for each of 5 seeds (the
// median of 5000 correlated second differences: measured spread about 2 %)
TEST(NoiseEstimateTest, WhiteNoiseOnASmoothSignal) {
  for (int seed = 1; seed <= 5; ++seed) {
    const double s = EstimateNoiseStd(NoisySine(0.01, seed));
    std::printf("[ measured ] seed %d: estimate %.5g for sigma 0.01\n", seed, s);
    EXPECT_NEAR(s, 0.01, 1e-3);
  }
}

// noise-free: only the sine's curvature, (2 pi 0.7)^2 1e-6 ~ 2e-5 per second difference
TEST(NoiseEstimateTest, NoiseFreeIsTheCurvatureOnly) {
  const double s = EstimateNoiseStd(NoisySine(0, 1));
  std::printf("[ measured ] noise-free: estimate %.3g\n", s);
  EXPECT_LT(s, 2e-5);
}

// impacts: 2 % of samples jump by +-0.5 (50 sigma); the median ignores them (within 15 %)
TEST(NoiseEstimateTest, JumpsDoNotInflateIt) {
  Eigen::VectorXd y = NoisySine(0.01, 3);
  for (int k = 17; k < y.size(); k += 50) y[k] += (k % 100 < 50 ? 0.5 : -0.5);
  const double s = EstimateNoiseStd(y);
  std::printf("[ measured ] with jumps: estimate %.5g for sigma 0.01\n", s);
  EXPECT_NEAR(s, 0.01, 1.5e-3);
}

// an encoder: a slow noise-free sine rounded to q = 1e-3: the estimate is the rounding's noise,
// q / sqrt(12) = 2.89e-4 within 30 % (the mean square of the whole-quanta second differences;
// their median, q, read 6.05e-4 before); with white noise 2e-3 before the rounding, that noise
// and the rounding's, sqrt(2e-3^2 + q^2 / 12) = 2.02e-3, within 10 %
TEST(NoiseEstimateTest, QuantizedDataGetTheQuantizationNoise) {
  Eigen::VectorXd y = NoisySine(0, 1);
  for (double& v : y) v = 1e-3 * std::round(v / 1e-3);
  const double s = EstimateNoiseStd(y);
  std::printf("[ measured ] quantized: estimate %.4g\n", s);
  EXPECT_GE(s, 1e-3 / std::sqrt(12.0));
  EXPECT_LE(s, 1.3e-3 / std::sqrt(12.0));
  Eigen::VectorXd noisy = NoisySine(2e-3, 1);
  for (double& v : noisy) v = 1e-3 * std::round(v / 1e-3);
  const double n = EstimateNoiseStd(noisy);
  std::printf("[ measured ] quantized, noise 2e-3: estimate %.4g\n", n);
  EXPECT_NEAR(n, std::sqrt(4e-6 + 1e-6 / 12), 2e-4);
  // a slower signal: most second differences are 0 and the floor decides
  Eigen::VectorXd slow(5000);
  for (int k = 0; k < slow.size(); ++k)
    slow[k] = 1e-3 * std::round(0.3 * std::sin(1e-4 * k) / 1e-3);
  const double f = EstimateNoiseStd(slow);
  std::printf("[ measured ] quantized, slow: estimate %.4g\n", f);
  EXPECT_NEAR(f, 1e-3 / std::sqrt(12.0), 1e-9);
}

// missing samples (every 7th NaN) are skipped; fewer than 8 measured triples give NaN
TEST(NoiseEstimateTest, MissingSamplesAreSkipped) {
  Eigen::VectorXd y = NoisySine(0.01, 4);
  for (int k = 0; k < y.size(); k += 7) y[k] = std::numeric_limits<double>::quiet_NaN();
  EXPECT_NEAR(EstimateNoiseStd(y), 0.01, 1e-3);
  Eigen::VectorXd few = NoisySine(0.01, 4).head(12);
  for (int k = 0; k < few.size(); k += 3) few[k] = std::numeric_limits<double>::quiet_NaN();
  EXPECT_TRUE(std::isnan(EstimateNoiseStd(few)));
  EXPECT_TRUE(std::isnan(EstimateNoiseStd(Eigen::VectorXd::Zero(5))));
}

}  // namespace
}  // namespace mjsysid
