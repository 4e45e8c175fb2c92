// Chi-square quantiles and the cost-excess test (sysid/assess/chi_square.h).
#include "sysid/assess/chi_square.h"

#include <algorithm>
#include <cmath>

namespace mjsysid {
namespace {

// one-sided false-alarm rate 1e-3
constexpr double kExcessZ = 3.090232306167813;

}  // namespace

double Chi2Quantile(double dof, double z) {
  if (!(dof > 0)) return 0;
  const double a = 2.0 / (9.0 * dof);
  return dof * std::pow(1.0 - a + z * std::sqrt(a), 3);
}

bool AboveByMoreThanNoise(double higher, double lower, double s2, int np) {
  if (!(s2 > 0) || !std::isfinite(s2)) s2 = 1.0;
  const double excess = 2.0 * (higher - lower) / s2;
  return excess > Chi2Quantile(std::max(np, 1), kExcessZ);
}

}  // namespace mjsysid
