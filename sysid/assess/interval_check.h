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

// Where CheckIntervalScale fails on a rugged cost (contacts: the cost jumps where a contact comes
// one step earlier or later), the jumps are the timing of contact events, not information about
// the parameters, and the question is whether the Jacobian's intervals still bound the estimate.
// CheckRuggedEnvelope evaluates the cost at every variable's estimate +- 1 and +- 2 standard
// errors (4 evaluations each; a side outside the bounds or failing is skipped) and asks two
// things of each:
// - no lower point: no cost there is below the estimate's by more than the noise explains
//   (sysid/assess/chi_square.h, AboveByMoreThanNoise, 1 degree of freedom, s2 the residual
//   variance); else the estimate is not the bottom of its own interval (`lower` says where);
// - the cost rises at least as fast as the quadratic model: where it rises less (actual change
//   below the predicted one, both in cost units), the variable's interval widens by
//   sqrt(predicted / actual) at the worst such point (widen[v] >= 1); a change <= 0 at 2
//   standard errors that is not a lower point leaves the interval unbounded (at 1: skipped).
// Envelope intervals are valid (`valid`) when no lower point exists and every interval is bounded:
// then the Jacobian's standard errors times widen are the intervals, marked as those of a rugged
// cost. Measured on the outside suite (docs/numerics.md, "Contact: intervals on a rugged cost").
struct RuggedEnvelope {
  bool valid = false;
  int checked = 0;        // cost evaluations made
  Eigen::VectorXd widen;  // per variable of std_error, >= 1 (1 where nothing widened)
  std::string lower;      // "NAME +2 std: cost -A" for the lowest point found below the estimate
  std::string unbounded;  // "NAME -1 std: cost +A" for a point that did not rise
  std::string widest;     // "NAME x1.8" for the largest widening ("" when none reaches 1 %)
};

RuggedEnvelope CheckRuggedEnvelope(const Eigen::VectorXd& r, const RowMatrix& J,
                                   const Eigen::VectorXd& std_error,
                                   const std::vector<std::string>& names, double s2,
                                   const std::function<bool(int, double, double*)>& cost_at);

// Where the check can find something. The cost jumps where the constraint forces switch branch:
// a contact or limit that comes or goes, a friction row between sticking and slipping (MuJoCo's
// constraint forces are smooth functions of the state on each branch). The nominal rollouts at
// the estimate (the ones the Jacobian and the intervals come from) tell whether any did:
struct CostSmoothness {
  bool all_rollouts = true;        // every segment's rollout at the estimate was seen (false: e.g.
                                   // a sharded fit, whose rollouts live on other ranks)
  long long steps = 0;             // steps of those rollouts
  long long contact_steps = 0;     // steps with a contact (Trajectory::ncon > 0)
  long long row_changes = 0;       // steps whose constraint rows changed (SolverStats::row_changes)
  long long friction_changes = 0;  // friction loss between sticking and slipping (kinks only)
  bool pgs_constraints = false;  // steps with constraint rows under PGS (no row states to compare)
  int kinks = 0;                 // one-sided differences of the Jacobian at the estimate
  int jacobian_warnings = 0;     // core Jacobian warnings in the solve or at the estimate
  bool robust_loss = false;      // a robust loss (Huber, Cauchy) bends the cost itself
  int fitted_delays = 0;         // fitted sensor and control delays (interpolated: kinks)
};

// Why the cost near the estimate can be rugged along the simulator parameters (the check runs
// along all of them), or "" when the rollouts followed one smooth branch throughout, without a
// contact, a constraint row that came, went or changed state, a kink or a Jacobian warning, under
// plain least squares without fitted delays (a robust loss is not quadratic in the residuals, a
// delay interpolates between samples; measured: the cart-pole with 5 % outliers under Cauchy
// fails the check at a standard error of 2 % of its value, the pendulum with a fitted control
// delay along its damping at 0.26 %).
// On such rollouts the check runs only along the simulator parameters whose standard error
// exceeds kSmoothRelativeStd of their value (CheckAlongSmooth): a smooth cost can still leave its
// quadratic model over a wide interval (measured: a LuGre bristle stiffness at 43 %), never over
// a narrow one in the unit, stress, robust and recovery suites (docs/numerics.md). Variables that
// need no rollout (measurement terms) and the fitted control delays (their held controls have a
// kink at every sample) are checked either way.
std::string RuggedReason(const CostSmoothness& s);

// the start of the warning a fit pass gives when the check failed and no envelope held (the
// cost is not what the Jacobian predicts one standard error away: the intervals describe nothing)
inline constexpr char kCostNotSmoothWarning[] =
    "the cost is not smooth at the scale of the intervals";

inline constexpr double kSmoothRelativeStd = 0.1;
// whether the check runs along a simulator parameter of this value and standard error when the
// rollouts are smooth (RuggedReason ""): se > kSmoothRelativeStd |value| (a value 0: always)
bool CheckAlongSmooth(double value, double se);

}  // namespace mjsysid
