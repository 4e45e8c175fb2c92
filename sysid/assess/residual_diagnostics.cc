// Residual diagnostics per channel: see sysid/assess/residual_diagnostics.h.
#include "sysid/assess/residual_diagnostics.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <map>
#include <string>
#include <vector>

#include "core/text.h"

namespace mjsysid {
namespace {

constexpr double kNan = std::numeric_limits<double>::quiet_NaN();

// a bias above this many of its own standard errors is reported (chance gives ~2)
constexpr double kBiasUnits = 4.0;

// the longest lag the correlation time looks at (samples): residuals correlated beyond it are
// reported at this length (a model error that slow is a drift, said by the bias and the ratio)
constexpr int kMaxLag = 2000;

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
  auto autocovariance = [&](int k) {
    double c = 0;
    for (const Eigen::VectorXd& e : residuals) {
      for (Eigen::Index t = 0; t + k < e.size(); ++t) {
        if (std::isnan(e[t]) || std::isnan(e[t + k])) continue;
        c += (e[t] - d.mean) * (e[t + k] - d.mean);
      }
    }
    return c;
  };
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

std::vector<ResidualDiagnostics> DiagnoseFitResiduals(const std::vector<SequenceResult>& sequences,
                                                      const FitOptions& options) {
  // the channels in first-seen order, each with its columns over the sequences
  std::vector<std::string> names;
  std::map<std::string, std::vector<Eigen::VectorXd>> columns;
  std::map<std::string, double> sigmas;
  for (const SequenceResult& s : sequences) {
    Eigen::Index col = 0;
    for (size_t i = 0; i < s.sensor_names.size() && i < s.sensor_dims.size(); ++i) {
      const std::string& sensor = s.sensor_names[i];
      const bool has_sigma =
          std::find(options.sensors_with_sigma.begin(), options.sensors_with_sigma.end(), sensor) !=
          options.sensors_with_sigma.end();
      const auto weight = options.sensor_weights.find(sensor);
      const double sigma = has_sigma && weight != options.sensor_weights.end() && weight->second > 0
                               ? 1 / weight->second
                               : kNan;
      for (int c = 0; c < s.sensor_dims[i]; ++c, ++col) {
        if (col >= s.measured.cols() || col >= s.simulated_final.cols()) break;
        const std::string channel =
            s.sensor_dims[i] == 1 ? sensor : sensor + "[" + std::to_string(c) + "]";
        if (!columns.count(channel)) names.push_back(channel);
        columns[channel].push_back(s.simulated_final.col(col) - s.measured.col(col));
        sigmas[channel] = sigma;
      }
    }
  }
  std::vector<ResidualDiagnostics> out;
  for (const std::string& name : names) {
    out.push_back(DiagnoseResiduals(name, columns[name], sigmas[name]));
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
