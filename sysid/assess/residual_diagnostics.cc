// Residual diagnostics per channel: see sysid/assess/residual_diagnostics.h.
#include "sysid/assess/residual_diagnostics.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <map>
#include <string>
#include <vector>

#include "core/text.h"
#include "sysid/assess/metrics.h"

namespace mjsysid {
namespace {

constexpr double kNan = std::numeric_limits<double>::quiet_NaN();

// a bias above this many of its own standard errors is reported (chance gives ~2)
constexpr double kBiasUnits = 4.0;

// the longest lag the correlation time looks at (samples): residuals correlated beyond it are
// reported at this length (a model error that slow is a drift, said by the bias and the ratio)
constexpr int kMaxLag = 2000;

// the sum over pairs of measured rows k apart within one sequence of the residuals' products,
// centred on `mean` (the autocovariance at lag k times the number of rows)
double LagSum(const std::vector<Eigen::VectorXd>& residuals, double mean, int k) {
  double c = 0;
  for (const Eigen::VectorXd& e : residuals) {
    for (Eigen::Index t = 0; t + k < e.size(); ++t) {
      if (std::isnan(e[t]) || std::isnan(e[t + k])) continue;
      c += (e[t] - mean) * (e[t + k] - mean);
    }
  }
  return c;
}

}  // namespace

double Chi2Survival(double x, double dof) {
  if (!(dof > 0)) return kNan;
  if (!(x > 0)) return 1.0;
  // Wilson-Hilferty: (X / dof)^(1/3) is nearly normal with mean 1 - 2 / (9 dof), variance
  // 2 / (9 dof) (as Chi2Quantile, sysid/assess/chi_square.h)
  const double v = 2.0 / (9.0 * dof);
  const double z = (std::cbrt(x / dof) - (1.0 - v)) / std::sqrt(v);
  return 0.5 * std::erfc(z / std::sqrt(2.0));
}

ResidualDiagnostics DiagnoseResiduals(const std::string& channel,
                                      const std::vector<Eigen::VectorXd>& residuals, double sigma) {
  ResidualDiagnostics d;
  d.channel = channel;
  d.sigma = sigma;
  // mean and rms over the measured rows of every sequence
  double sum = 0, sum2 = 0;
  for (const Eigen::VectorXd& e : residuals) {
    for (Eigen::Index k = 0; k < e.size(); ++k) {
      if (std::isnan(e[k])) continue;
      sum += e[k];
      sum2 += e[k] * e[k];
      ++d.samples;
    }
  }
  if (d.samples == 0) {
    d.mean = d.rms = d.ratio = d.bias_units = d.lag1 = d.tau = d.portmanteau_p = kNan;
    return d;
  }
  const double n = static_cast<double>(d.samples);
  d.mean = sum / n;
  d.rms = std::sqrt(sum2 / n);
  d.ratio = std::isfinite(sigma) && sigma > 0 ? d.rms / sigma : kNan;
  d.lag1 = d.tau = d.portmanteau_p = d.bias_units = kNan;
  if (d.samples < 4 * kPortmanteauLags) return d;

  // autocovariance of the centred residuals at row lag k, pairs within one sequence
  size_t longest = 0;
  for (const Eigen::VectorXd& e : residuals) longest = std::max<size_t>(longest, e.size());
  const int max_lag = std::min(kMaxLag, std::max(kPortmanteauLags, static_cast<int>(longest / 4)));
  auto autocovariance = [&](int k) { return LagSum(residuals, d.mean, k); };
  const double c0 = autocovariance(0);
  if (!(c0 > 0)) {  // residuals exactly constant: nothing to correlate
    d.lag1 = 0;
    d.tau = 1;
    d.portmanteau_p = 1;
    d.bias_units = d.mean == 0 ? 0 : std::numeric_limits<double>::infinity();
    d.white = true;
    return d;
  }
  // rho(k): the standard (biased) estimate, sum over the pairs / sum of squares, which keeps the
  // sequence positive definite; lags as far as Sokal's window or the Ljung-Box lags need
  std::vector<double> rho(1, 1.0);
  double tau = 1;
  bool window_found = false;
  for (int k = 1; k <= max_lag; ++k) {
    rho.push_back(autocovariance(k) / c0);
    if (!window_found) {
      tau += 2 * rho[k];
      window_found = k >= kTauWindowFactor * tau;
    }
    if (window_found && k >= kPortmanteauLags) break;
  }
  d.lag1 = rho[1];
  d.tau = std::max(1.0, tau);

  // Ljung-Box over kPortmanteauLags lags
  double q = 0;
  for (int k = 1; k <= kPortmanteauLags; ++k) q += rho[k] * rho[k] / (n - k);
  q *= n * (n + 2);
  d.portmanteau_p = Chi2Survival(q, kPortmanteauLags);
  d.white = d.portmanteau_p > kWhitenessLevel;
  d.bias_units = std::abs(d.mean) / (std::sqrt(c0 / n) / std::sqrt(n / d.tau));
  return d;
}

std::vector<ChannelResiduals> PoolResidualsByChannel(const std::vector<SequenceResult>& sequences) {
  std::vector<ChannelResiduals> out;
  std::map<std::string, size_t> index;  // channel -> its place in out
  for (const SequenceResult& s : sequences) {
    const std::vector<std::string> channels = ChannelNames(s);
    Eigen::Index col = 0;
    for (size_t i = 0; i < s.sensor_names.size() && i < s.sensor_dims.size(); ++i) {
      for (int c = 0; c < s.sensor_dims[i]; ++c, ++col) {
        if (col >= s.measured.cols() || col >= s.simulated_final.cols()) break;
        const std::string& channel = channels[static_cast<size_t>(col)];
        const auto [at, added] = index.emplace(channel, out.size());
        if (added) out.push_back(ChannelResiduals{channel, s.sensor_names[i], {}});
        out[at->second].columns.push_back(s.simulated_final.col(col) - s.measured.col(col));
      }
    }
  }
  return out;
}

Eigen::VectorXd ResidualAutocorrelation(const std::vector<Eigen::VectorXd>& residuals,
                                        int max_lag) {
  Eigen::VectorXd rho = Eigen::VectorXd::Constant(std::max(0, max_lag) + 1, kNan);
  double sum = 0;
  int n = 0;
  for (const Eigen::VectorXd& e : residuals) {
    for (Eigen::Index k = 0; k < e.size(); ++k) {
      if (std::isnan(e[k])) continue;
      sum += e[k];
      ++n;
    }
  }
  if (n < 2) return rho;
  const double mean = sum / n, c0 = LagSum(residuals, mean, 0);
  // constant residuals (up to the rounding of their mean) have no autocorrelation
  const double rounding = 1e-12 * std::abs(mean);
  if (!(c0 > n * rounding * rounding)) return rho;
  for (Eigen::Index k = 0; k < rho.size(); ++k) {
    rho[k] = LagSum(residuals, mean, static_cast<int>(k)) / c0;
  }
  return rho;
}

std::vector<ResidualDiagnostics> DiagnoseFitResiduals(const std::vector<SequenceResult>& sequences,
                                                      const FitOptions& options) {
  std::vector<ResidualDiagnostics> out;
  for (const ChannelResiduals& c : PoolResidualsByChannel(sequences)) {
    // the stated sigma of the channel's sensor: 1 / its weight
    const bool has_sigma =
        std::find(options.sensors_with_sigma.begin(), options.sensors_with_sigma.end(), c.sensor) !=
        options.sensors_with_sigma.end();
    const auto weight = options.sensor_weights.find(c.sensor);
    const double sigma = has_sigma && weight != options.sensor_weights.end() && weight->second > 0
                             ? 1 / weight->second
                             : kNan;
    out.push_back(DiagnoseResiduals(c.channel, c.columns, sigma));
  }
  return out;
}

double CorrelationInflation(const std::vector<ResidualDiagnostics>& residuals,
                            std::string* channel) {
  double factor = 1;
  channel->clear();
  for (const ResidualDiagnostics& d : residuals) {
    if (d.white || !(d.tau > factor)) continue;
    factor = d.tau;
    *channel = d.channel;
  }
  return factor;
}

std::string ResidualSentence(const ResidualDiagnostics& d) {
  std::string s;
  if (!d.white) {
    s = "'" + d.channel + "': residuals are not white noise (correlated over " +
        FormatDigits(d.tau, 2) + " samples, lag-1 correlation " + FormatDigits(d.lag1, 2) +
        "): they carry something the model does not reproduce (model error, filtering, stamp " +
        "jitter), not only sensor noise";
  }
  if (std::isfinite(d.bias_units) && d.bias_units > kBiasUnits) {
    s += std::string(s.empty() ? "'" + d.channel + "': " : "; ") + "residuals are biased by " +
         FormatDigits(d.mean, 3) + " (" + FormatDigits(d.bias_units, 2) +
         " of their own standard errors): an offset the model lacks (a sensor bias, gravity, a " +
         "zero position)";
  }
  return s;
}

}  // namespace mjsysid
