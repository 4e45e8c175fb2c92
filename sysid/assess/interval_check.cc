// The cost at an estimate +- one standard error against its Jacobian's quadratic model: see
// sysid/interval_check.h.
#include "sysid/assess/interval_check.h"

#include <algorithm>
#include <cmath>

#include "core/text.h"
#include "sysid/assess/chi_square.h"

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

RuggedEnvelope CheckRuggedEnvelope(const Eigen::VectorXd& r, const RowMatrix& J,
                                   const Eigen::VectorXd& std_error,
                                   const std::vector<std::string>& names, double s2,
                                   const std::function<bool(int, double, double*)>& cost_at) {
  RuggedEnvelope env;
  env.widen = Eigen::VectorXd::Ones(std_error.size());
  const double cost0 = 0.5 * r.squaredNorm();
  double lowest = 0, widest = 1;
  for (Eigen::Index v = 0; v < std_error.size(); ++v) {
    const double se = std_error[v];
    if (!std::isfinite(se) || !(se > 0)) continue;
    for (const double k : {1.0, -1.0, 2.0, -2.0}) {
      const double delta = k * se;
      double cost = 0;
      if (!cost_at(static_cast<int>(v), delta, &cost) || !std::isfinite(cost)) continue;
      ++env.checked;
      const double actual = cost - cost0;
      const double predicted = 0.5 * (r + delta * J.col(v)).squaredNorm() - cost0;
      const std::string where = names[v] + (k > 0 ? " +" : " ") + FormatDigits(k, 2) +
                                " std: cost " + (actual >= 0 ? "+" : "") + FormatDigits(actual, 3);
      // a point below the estimate by more than the noise explains
      if (AboveByMoreThanNoise(cost0, cost, s2, 1)) {
        if (actual < lowest) {
          lowest = actual;
          env.lower = where;
        }
        continue;
      }
      // no rise: within the noise at 1 std, unbounded at 2 (the interval reaches past it)
      if (!(actual > 0)) {
        if (std::abs(k) > 1 && env.unbounded.empty()) env.unbounded = where;
        continue;
      }
      // a rise slower than the model's widens the interval to match it
      if (predicted > actual) {
        const double f = std::sqrt(predicted / actual);
        env.widen[v] = std::max(env.widen[v], f);
        if (f > widest && f >= 1.01) {
          widest = f;
          env.widest = names[v] + " x" + FormatDigits(f, 3);
        }
      }
    }
  }
  env.valid = env.lower.empty() && env.unbounded.empty();
  return env;
}

std::string RuggedReason(const CostSmoothness& s) {
  if (!s.all_rollouts) return "the rollouts at the estimate are not all on this process";
  const std::string of = " of " + std::to_string(s.steps) + " steps";
  if (s.contact_steps > 0) return "contacts in " + std::to_string(s.contact_steps) + of;
  if (s.row_changes > 0) {
    return "constraint rows come, go or change state (sticking, slipping) in " +
           std::to_string(s.row_changes) + of;
  }
  if (s.robust_loss) return "a robust loss: the cost is not quadratic in the residuals";
  if (s.fitted_delays > 0) {
    return std::to_string(s.fitted_delays) + " fitted delays (interpolated between samples)";
  }
  if (s.pgs_constraints) return "constraint rows solved by PGS (their states are not compared)";
  if (s.kinks > 0) return std::to_string(s.kinks) + " kinks in the Jacobian at the estimate";
  if (s.jacobian_warnings > 0) {
    return std::to_string(s.jacobian_warnings) + " core Jacobian warnings";
  }
  return "";
}

bool CheckAlongSmooth(double value, double se) {
  return !(se <= kSmoothRelativeStd * std::abs(value));
}

}  // namespace mjsysid
