#include "sysid/assess/noise_estimate.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <vector>

namespace mjsysid {

double EstimateNoiseStd(const Eigen::Ref<const Eigen::VectorXd>& y) {
  constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();
  // second differences over consecutive measured triples; the smallest nonzero first difference
  std::vector<double> d2;
  d2.reserve(static_cast<size_t>(std::max<Eigen::Index>(0, y.size() - 2)));
  double quantum = std::numeric_limits<double>::infinity();
  for (Eigen::Index k = 1; k < y.size(); ++k) {
    const double step = std::abs(y[k] - y[k - 1]);
    if (std::isfinite(step) && step > 0) quantum = std::min(quantum, step);
    if (k + 1 < y.size()) {
      const double d = y[k + 1] - 2 * y[k] + y[k - 1];
      if (std::isfinite(d)) d2.push_back(std::abs(d));
    }
  }
  if (d2.size() < 8) return kNaN;
  // the median absolute second difference, scaled to the noise std (1.4826 / sqrt(6))
  const auto mid = d2.begin() + static_cast<std::ptrdiff_t>(d2.size() / 2);
  std::nth_element(d2.begin(), mid, d2.end());
  const double sigma = 1.482602218505602 * *mid / std::sqrt(6.0);
  // at least the quantization noise of the smallest step seen
  const double quantized = std::isfinite(quantum) ? quantum / std::sqrt(12.0) : 0.0;
  return std::max(sigma, quantized);
}

}  // namespace mjsysid
