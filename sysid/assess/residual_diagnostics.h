// Whether a fit's residuals look like the white noise its intervals assume, channel by channel
// (docs/real-logs.md, "Residual diagnostics"). Eigen only.
//
// For one channel (a sensor column, or a fitted state's), the residuals e = simulated - measured
// at the estimate over one or more sequences, rows in sample order, NaN where not measured:
// - bias: mean(e), and its size against the noise the residuals themselves show, |mean| / (rms /
//   sqrt(n_eff)) with std their spread about the mean and n_eff = n / tau (a bias of a few such
//   units is chance, more is model error).
// - ratio: rms(e) / sigma (the stated sigma; NaN without one): ~1 when the residuals are the
//   noise the user stated, above when the model leaves part of the motion unexplained.
// - autocorrelation rho(k) of the centred residuals, pairs of measured rows k apart within one
//   sequence (row lags: a log with jitter and gaps is taken at its mean rate).
// - tau, the integrated correlation time in samples, 1 + 2 sum_{k=1}^{W} rho(k), with Sokal's
//   window: the smallest W >= kTauWindowFactor * tau(W) (at most a quarter of the rows). White
//   noise gives ~1; residuals that carry model error (a coarser step, a missing term) or stamp
//   jitter are correlated over many samples: tau counts how many samples carry one independent
//   piece of information.
// - the Ljung-Box portmanteau Q = n (n + 2) sum_{k=1}^{h} rho(k)^2 / (n - k) over h =
//   kPortmanteauLags lags, chi-square with h degrees of freedom under white noise; white when its
//   p-value is above kWhitenessLevel.
// Failure: a channel with fewer than 4 h measured samples has NaN for everything but rms, bias
// and ratio, and counts as white (too short to tell).
#pragma once

#include <Eigen/Core>
#include <string>
#include <vector>

#include "sysid/types.h"

namespace mjsysid {

constexpr int kPortmanteauLags = 20;
constexpr double kWhitenessLevel = 1e-3;
constexpr double kTauWindowFactor = 5.0;

// One channel's diagnostics over its sequences: residuals[q] is sequence q's column (NaN: not
// measured); sigma the stated noise (NaN: none).
ResidualDiagnostics DiagnoseResiduals(const std::string& channel,
                                      const std::vector<Eigen::VectorXd>& residuals, double sigma);

// the upper tail of the chi-square distribution with dof degrees of freedom at x: P(X > x)
double Chi2Survival(double x, double dof);

// The residual columns simulated_final - measured of every fitted sensor column of sequences,
// pooled by channel name (metrics.h ChannelNames) over the sequences, in first-seen order (what
// DiagnoseFitResiduals diagnoses, and the report plots)
struct ChannelResiduals {
  std::string channel, sensor;  // "sensor" or "sensor[i]"; the sensor's name
  std::vector<Eigen::VectorXd>
      columns;  // one per sequence that has the channel (NaN: not measured)
};
std::vector<ChannelResiduals> PoolResidualsByChannel(const std::vector<SequenceResult>& sequences);

// rho(0..max_lag) of the residuals centred on their pooled mean: pairs of measured rows k apart
// within one sequence (rows with NaN left out), over the sum of squares (the standard biased
// estimate, as DiagnoseResiduals uses); rho(0) = 1. NaN at every lag when fewer than two rows are
// measured or the residuals are constant (to the rounding of their mean). max_lag >= 0.
Eigen::VectorXd ResidualAutocorrelation(const std::vector<Eigen::VectorXd>& residuals, int max_lag);

// Every fitted sensor column of sequences, pooled by channel name over the sequences (first-seen
// order): residual simulated_final - measured; the sigma of a sensor in options.sensors_with_sigma
// is 1 / its weight.
std::vector<ResidualDiagnostics> DiagnoseFitResiduals(const std::vector<SequenceResult>& sequences,
                                                      const FitOptions& options);

// The factor for a covariance from white-noise theory when the residuals are correlated: with
// slowly varying sensitivities (the rollouts' own), the variance of an estimate from residuals
// correlated over tau samples is tau times the white-noise one (n / tau independent pieces). The
// largest tau of the channels that are not white; 1 when every channel is white. *channel: the
// channel it came from ("" when 1).
double CorrelationInflation(const std::vector<ResidualDiagnostics>& residuals,
                            std::string* channel);

// one plain sentence on a channel that is not white or is biased (empty when it is neither)
std::string ResidualSentence(const ResidualDiagnostics& d);

}  // namespace mjsysid
