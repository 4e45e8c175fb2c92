// Whether the cost near an estimate is what its Jacobian says: the check behind a fit's intervals
// (docs/numerics.md, "Contact: a rugged cost").
//
// The intervals of a fit come from the local quadratic model of the cost,
//   cost(p + delta e_v) ~ 0.5 |r + J_v delta|^2,
// with r the residuals and J_v the Jacobian column of variable v at the estimate. Contacts that
// switch on and off, impacts and stick-slip make a rollout jump when a parameter moves by far less
// than its standard error (measured: a sliding box's cost jumps by 1.3 % at a friction change of
// 5e-7 relative, and is 5x its minimum at 4e-5, 0.2 standard errors). Then the Jacobian is exact
// (it agrees with central differences at 1e-7) but describes the cost only over a sliver, and the
// intervals built from it describe nothing.
//
// CheckIntervalScale evaluates the cost at v's estimate +- its standard error, for every variable
// with a finite positive standard error, and compares the change with the quadratic model's:
// the model fails where |actual - predicted| > 1 + |predicted| (cost units 0.5 |r|^2: one standard
// error along a variable raises the model's cost by 0.5 or more). Shapes: r has m entries, J is
// m x n (its first n_checked columns are the variables checked), std_error has n_checked entries.
// cost_at(v, delta, &cost) evaluates the total cost with variable v moved by delta (physical units)
// and returns false when it cannot (a bound, a failed simulation): that side is skipped.
#pragma once

#include <Eigen/Core>
#include <functional>
#include <string>
#include <vector>

#include "core/state.h"

namespace mjsysid {

struct IntervalCheck {
  bool local = true;        // the quadratic model held at +- one standard error for every variable
  int checked = 0;          // cost evaluations made
  std::string worst;        // "NAME +1 std: cost +A (Jacobian predicts +B)" for the worst variable
  double worst_excess = 0;  // |actual - predicted| / (1 + |predicted|) there
};

IntervalCheck CheckIntervalScale(const Eigen::VectorXd& r, const RowMatrix& J,
                                 const Eigen::VectorXd& std_error,
                                 const std::vector<std::string>& names,
                                 const std::function<bool(int, double, double*)>& cost_at);

}  // namespace mjsysid
