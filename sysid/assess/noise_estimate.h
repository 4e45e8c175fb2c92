// The measurement noise of a logged column, estimated from the log alone, and the test that a fit
// without sigmas explains its data (sysid/assess/fit_status.h uses both). Eigen only.
//
// Noise: for y_k = s(t_k) + e_k with e white (std sigma) and s smooth at the sampling rate, the
// second difference d_k = y_{k+1} - 2 y_k + y_{k-1} is ~N(0, 6 sigma^2) plus s'' dt^2. The
// estimate is the median absolute second difference scaled to a std,
//   sigma_hat = 1.4826 median|d_k| / sqrt(6),
// robust to jumps (impacts, gaps) that a few d_k carry. On uneven stamps (logged jitter, dropped
// rows) d_k is the difference that cancels a slope between them, scaled alike. A signal that is not
// smooth at the sampling rate, or stamp jitter the stamps do not show, adds to it (the estimate
// errs large: a fit is then called unexplained less often, never more). Quantized data (every step
// between consecutive samples a whole number of quanta, the quantum being the smallest nonzero
// step) take sqrt(mean d_k^2 / 6) instead, the largest 2 % of d_k left out and the mean scaled to a
// Gaussian's (the median of whole quanta jumps between 0, q and 2q), and at least the quantum /
// sqrt(12): an encoder's rounding, or the noise above it. Noise filtered before logging (correlated
// over many samples) is underestimated: give sigmas for such sensors.
#pragma once

#include <Eigen/Core>

namespace mjsysid {

// sigma_hat of column y (T samples; NaN samples skipped: only triples of consecutive measured
// samples count); NaN when fewer than 8 such triples exist. With the samples' times (T, s,
// increasing; another length: evenly spaced) the second differences follow the stamps (a
// logged jitter or gap is not read as noise: on uneven stamps the plain difference carries the
// slope times the jitter)
double EstimateNoiseStd(const Eigen::Ref<const Eigen::VectorXd>& y,
                        const Eigen::Ref<const Eigen::VectorXd>& time);
double EstimateNoiseStd(const Eigen::Ref<const Eigen::VectorXd>& y);

// A channel without a sigma is unexplained at the estimate when both hold:
// - its residual RMS exceeds kUnexplainedNoiseFactor x its estimated noise: the residual is not
//   the log's noise (5: a chi-square ratio of 25, where the test with sigmas stops at 2; the
//   estimate of white noise is within 10 % over thousands of samples, so only model error or
//   noise filtered before logging gets there; measured: a pendulum fitted without its friction
//   leaves 9.6 x the rate's noise, tests/sysid/status_test.cc);
// - its % fit (sysid/assess/metrics.h) is below kUnexplainedFitPercent: the residual is a visible
//   part of the motion, not a rounding of it (this keeps noise-free logs, whose estimated noise is
//   ~0, from failing on the solver's last digits).
constexpr double kUnexplainedNoiseFactor = 5.0;
constexpr double kUnexplainedFitPercent = 90.0;

}  // namespace mjsysid
