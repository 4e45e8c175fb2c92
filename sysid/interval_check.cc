// The cost at an estimate +- one standard error against its Jacobian's quadratic model: see
// sysid/interval_check.h.
#include "sysid/interval_check.h"

#include <cmath>

#include "core/text.h"

namespace mjsysid {

IntervalCheck CheckIntervalScale(const Eigen::VectorXd& r, const RowMatrix& J,
                                 const Eigen::VectorXd& std_error,
                                 const std::vector<std::string>& names,
                                 const std::function<bool(int, double, double*)>& cost_at) {
  IntervalCheck check;
  const double cost0 = 0.5 * r.squaredNorm();
  for (Eigen::Index v = 0; v < std_error.size(); ++v) {
    const double se = std_error[v];
    if (!std::isfinite(se) || !(se > 0)) continue;
    for (const double sign : {1.0, -1.0}) {
      // the cost one standard error away, and what the quadratic model predicts there
      const double delta = sign * se;
      double cost = 0;
      if (!cost_at(static_cast<int>(v), delta, &cost) || !std::isfinite(cost)) continue;
      ++check.checked;
      const double actual = cost - cost0;
      const double predicted = 0.5 * (r + delta * J.col(v)).squaredNorm() - cost0;
      const double excess = std::abs(actual - predicted) / (1 + std::abs(predicted));
      if (excess > check.worst_excess) {
        check.worst_excess = excess;
        check.worst = names[v] + (sign > 0 ? " +1 std: cost " : " -1 std: cost ") +
                      (actual >= 0 ? "+" : "") + FormatDigits(actual, 3) + " (Jacobian predicts " +
                      (predicted >= 0 ? "+" : "") + FormatDigits(predicted, 3) + ")";
      }
      if (excess > 1) check.local = false;
    }
  }
  return check;
}

}  // namespace mjsysid
