#include "sysid/assess/noise_estimate.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <vector>

namespace mjsysid {

double EstimateNoiseStd(const Eigen::Ref<const Eigen::VectorXd>& y,
                        const Eigen::Ref<const Eigen::VectorXd>& time) {
  constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();
  const bool timed = time.size() == y.size();
  // second differences over consecutive measured triples, each scaled to the noise's std: on
  // uneven stamps h1 = t_k - t_(k-1), h2 = t_(k+1) - t_k the difference that cancels a constant
  // and a slope is h2 y_(k-1) - (h1 + h2) y_k + h1 y_(k+1), of noise variance
  // (h1^2 + (h1 + h2)^2 + h2^2) sigma^2 (6 sigma^2 on even stamps, where it is the plain one);
  // the smallest nonzero first difference is the quantum
  std::vector<double> d2;
  d2.reserve(static_cast<size_t>(std::max<Eigen::Index>(0, y.size() - 2)));
  double quantum = std::numeric_limits<double>::infinity();
  for (Eigen::Index k = 1; k < y.size(); ++k) {
    const double step = std::abs(y[k] - y[k - 1]);
    if (std::isfinite(step) && step > 0) quantum = std::min(quantum, step);
    if (k + 1 < y.size()) {
      const double h1 = timed ? time[k] - time[k - 1] : 1.0;
      const double h2 = timed ? time[k + 1] - time[k] : 1.0;
      const double d = (h2 * y[k - 1] - (h1 + h2) * y[k] + h1 * y[k + 1]) /
                       std::sqrt((h1 * h1 + (h1 + h2) * (h1 + h2) + h2 * h2) / 6);
      if (std::isfinite(d) && h1 > 0 && h2 > 0) d2.push_back(std::abs(d));
    }
  }
  if (d2.size() < 8) return kNaN;
  // at least the quantization noise of the smallest step seen
  const double floor = std::isfinite(quantum) ? quantum / std::sqrt(12.0) : 0.0;
  // quantized data (every step a whole number of quanta): the second differences are whole
  // quanta too, so their median jumps between 0, q and 2q and a staircase (noise below a quantum)
  // would read as 0.6 q, twice the quantization noise q / sqrt(12); their mean square (the largest
  // kTrimmed left out as jumps) over 6 is that noise, or the noise above it, smoothly
  bool whole = std::isfinite(quantum);
  for (Eigen::Index k = 1; whole && k < y.size(); ++k) {
    const double steps = std::abs(y[k] - y[k - 1]) / quantum;
    whole = !std::isfinite(steps) || std::abs(steps - std::round(steps)) < 1e-6 * (1 + steps);
  }
  if (whole) {
    // the largest 2 % left out; a Gaussian's mean square below its 98 % |d| quantile is 0.873462
    // of its variance (as 1.4826 makes a median a std)
    constexpr double kTrimmed = 0.02, kTrimmedShare = 0.873462;
    const auto keep = d2.begin() + static_cast<std::ptrdiff_t>(
                                       std::ceil((1 - kTrimmed) * static_cast<double>(d2.size())));
    std::nth_element(d2.begin(), keep - 1, d2.end());
    double sum = 0;
    for (auto it = d2.begin(); it != keep; ++it) sum += *it * *it;
    const double mean_square = sum / static_cast<double>(keep - d2.begin());
    return std::max(std::sqrt(mean_square / kTrimmedShare / 6), floor);
  }
  // the median absolute second difference, scaled to the noise std (1.4826 / sqrt(6))
  const auto mid = d2.begin() + static_cast<std::ptrdiff_t>(d2.size() / 2);
  std::nth_element(d2.begin(), mid, d2.end());
  const double sigma = 1.482602218505602 * *mid / std::sqrt(6.0);
  return std::max(sigma, floor);
}

double EstimateNoiseStd(const Eigen::Ref<const Eigen::VectorXd>& y) {
  return EstimateNoiseStd(y, Eigen::VectorXd());
}

}  // namespace mjsysid
