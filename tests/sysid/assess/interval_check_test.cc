// CheckIntervalScale (sysid/assess/interval_check.h): the cost at the estimate +- one standard
// error against the Jacobian's quadratic model, on hand-made residuals r(p) = a (p - p0) +
// noise-like offsets, smooth and with a jump inside the interval.
#include "sysid/assess/interval_check.h"

#include <gtest/gtest.h>

#include <Eigen/Dense>
#include <cmath>
#include <functional>

namespace mjsysid {
namespace {

// residuals of two variables: r_i = b_i + a_i0 x0 + a_i1 x1 (+ jump_i where x0 > jump_at)
struct Linear {
  RowMatrix A;
  Eigen::VectorXd b, jump;
  double jump_at = INFINITY;
  Eigen::VectorXd Residuals(const Eigen::Vector2d& x) const {
    Eigen::VectorXd r = b + A * x;
    if (x[0] > jump_at) r += jump;
    return r;
  }
};

Linear Make() {
  Linear f;
  f.A = RowMatrix::Zero(6, 2);
  f.A << 3, 0, 1, 1, 0, 2, -1, 0.5, 2, -1, 0, 1;
  f.b.resize(6);
  f.b << 0.3, -0.2, 0.1, 0.4, -0.5, 0.2;
  f.jump = Eigen::VectorXd::Constant(6, 3.0);
  return f;
}

IntervalCheck Check(const Linear& f, const Eigen::Vector2d& se) {
  const Eigen::Vector2d x0 = Eigen::Vector2d::Zero();
  return CheckIntervalScale(f.Residuals(x0), f.A, se, {"a", "b"},
                            [&](int v, double delta, double* cost) {
                              Eigen::Vector2d x = x0;
                              x[v] += delta;
                              *cost = 0.5 * f.Residuals(x).squaredNorm();
                              return true;
                            });
}

TEST(IntervalCheckTest, SmoothCostPassesAtAnyScale) {
  // a linear model is exactly its own quadratic model: no excess however large the step
  const Linear f = Make();
  for (double se : {1e-6, 1.0, 1e3}) {
    const IntervalCheck c = Check(f, Eigen::Vector2d(se, se));
    EXPECT_TRUE(c.local) << se << " " << c.worst;
    EXPECT_EQ(c.checked, 4);
    EXPECT_LT(c.worst_excess, 1e-9);
  }
}

TEST(IntervalCheckTest, JumpInsideTheIntervalFails) {
  // a residual jump of 3 per entry (cost +27 and more) at x0 = 0.05, inside +-0.1
  Linear f = Make();
  f.jump_at = 0.05;
  const IntervalCheck inside = Check(f, Eigen::Vector2d(0.1, 0.1));
  EXPECT_FALSE(inside.local);
  EXPECT_NE(inside.worst.find("a +1 std"), std::string::npos) << inside.worst;
  // the same jump outside the interval is not seen
  const IntervalCheck outside = Check(f, Eigen::Vector2d(0.01, 0.01));
  EXPECT_TRUE(outside.local) << outside.worst;
}

TEST(IntervalCheckTest, SkipsVariablesWithoutIntervalsAndSidesThatFail) {
  const Linear f = Make();
  // no interval (0: on a bound; inf: unidentifiable; NaN) is not checked
  const Eigen::VectorXd r = f.Residuals(Eigen::Vector2d::Zero());
  int calls = 0;
  const IntervalCheck c = CheckIntervalScale(r, f.A, Eigen::Vector2d(0.0, INFINITY), {"a", "b"},
                                             [&](int, double, double*) {
                                               ++calls;
                                               return true;
                                             });
  EXPECT_EQ(calls, 0);
  EXPECT_EQ(c.checked, 0);
  EXPECT_TRUE(c.local);
  // a side that cannot be evaluated is skipped, the other is checked
  const IntervalCheck one = CheckIntervalScale(
      r, f.A, Eigen::Vector2d(0.1, NAN), {"a", "b"}, [&](int, double delta, double* cost) {
        *cost = 0.5 * (r + delta * f.A.col(0)).squaredNorm() + 100;  // off by 100 (fails)
        return delta > 0;
      });
  EXPECT_EQ(one.checked, 1);
  EXPECT_FALSE(one.local);
  EXPECT_NE(one.worst.find("a +1 std"), std::string::npos) << one.worst;
}

// RuggedReason: every sign of a branch switch in the rollouts at the estimate keeps the check;
// rollouts without any (friction loss sticking and slipping alone: a kink, no jump) skip it
TEST(IntervalCheckTest, RuggedReasonNamesWhatSwitched) {
  const CostSmoothness smooth{true, 6000, 0, 0, 0, false, 0, 0};
  EXPECT_EQ(RuggedReason(smooth), "");
  CostSmoothness friction = smooth;
  friction.friction_changes = 40;
  EXPECT_EQ(RuggedReason(friction), "");
  CostSmoothness s = smooth;
  s.all_rollouts = false;
  EXPECT_NE(RuggedReason(s).find("not all"), std::string::npos);
  s = smooth;
  s.contact_steps = 3;
  EXPECT_EQ(RuggedReason(s), "contacts in 3 of 6000 steps");
  s = smooth;
  s.row_changes = 2;
  EXPECT_NE(RuggedReason(s).find("in 2 of 6000 steps"), std::string::npos) << RuggedReason(s);
  s = smooth;
  s.robust_loss = true;
  EXPECT_NE(RuggedReason(s).find("robust loss"), std::string::npos);
  s = smooth;
  s.fitted_delays = 2;
  EXPECT_EQ(RuggedReason(s), "2 fitted delays (interpolated between samples)");
  s = smooth;
  s.pgs_constraints = true;
  EXPECT_NE(RuggedReason(s).find("PGS"), std::string::npos);
  s = smooth;
  s.kinks = 1;
  EXPECT_NE(RuggedReason(s).find("kinks"), std::string::npos);
  s = smooth;
  s.jacobian_warnings = 1;
  EXPECT_NE(RuggedReason(s).find("Jacobian warnings"), std::string::npos);
}

// on smooth rollouts the check runs along a simulator parameter only where its standard error is
// wide against its value (kSmoothRelativeStd)
TEST(IntervalCheckTest, AlongSmoothRolloutsOnlyWideIntervalsAreChecked) {
  EXPECT_FALSE(CheckAlongSmooth(120.0, 1.0));                      // 0.8 %
  EXPECT_FALSE(CheckAlongSmooth(-2.0, kSmoothRelativeStd * 2.0));  // at the limit
  EXPECT_TRUE(CheckAlongSmooth(120.9, 51.7));                      // 43 %: LuGre's
  EXPECT_TRUE(CheckAlongSmooth(0.0, 1e-9));                        // no scale
  EXPECT_TRUE(CheckAlongSmooth(2.0, std::nextafter(0.2, 1.0)));    // just past it
}

// CheckRuggedEnvelope at the least-squares minimum of Make()'s residuals (J^T r = 0): the cost
// at +-1 and +-2 standard errors along each variable, here given by `cost` (the quadratic model
// itself, then changed), s2 = 1
struct Envelope {
  Linear f = Make();
  Eigen::VectorXd r;
  Eigen::Vector2d se;
  Envelope() {
    const Eigen::MatrixXd a = f.A;
    const Eigen::Vector2d x = -(a.transpose() * a).ldlt().solve(a.transpose() * f.b);
    r = f.b + f.A * x;
    // standard errors of a unit residual variance: sqrt(diag((J^T J)^-1))
    se = (a.transpose() * a).inverse().diagonal().cwiseSqrt();
  }
  double Model(int v, double delta) const { return 0.5 * (r + delta * f.A.col(v)).squaredNorm(); }
  RuggedEnvelope Check(const std::function<double(int, double)>& cost) const {
    return CheckRuggedEnvelope(r, f.A, se, {"a", "b"}, 1.0, [&](int v, double d, double* c) {
      *c = cost(v, d);
      return true;
    });
  }
};

// the quadratic model itself, and a cost that jumps upward inside the interval (contact events):
// valid, nothing widened, 8 evaluations
TEST(IntervalCheckTest, EnvelopeOfACostThatRisesIsValid) {
  const Envelope e;
  RuggedEnvelope env = e.Check([&](int v, double d) { return e.Model(v, d); });
  EXPECT_TRUE(env.valid);
  EXPECT_EQ(env.checked, 8);
  EXPECT_EQ(env.widen, Eigen::Vector2d::Ones());
  EXPECT_EQ(env.widest, "");
  env = e.Check(
      [&](int v, double d) { return e.Model(v, d) + (std::abs(d) > 0.3 * e.se[v] ? 800.0 : 0.0); });
  EXPECT_TRUE(env.valid);
  EXPECT_EQ(env.widen, Eigen::Vector2d::Ones());
}

// a cost that rises at a quarter of the model's rate along `a`: a's interval widens by 2
TEST(IntervalCheckTest, EnvelopeWidensWhereTheCostRisesSlower) {
  const Envelope e;
  const double c0 = 0.5 * e.r.squaredNorm();
  const RuggedEnvelope env = e.Check(
      [&](int v, double d) { return v == 0 ? c0 + 0.25 * (e.Model(v, d) - c0) : e.Model(v, d); });
  EXPECT_TRUE(env.valid);
  EXPECT_NEAR(env.widen[0], 2.0, 1e-12);
  EXPECT_EQ(env.widen[1], 1.0);
  EXPECT_EQ(env.widest, "a x2");
}

// a point 2 standard errors out below the estimate by more than the noise explains (the
// chi-square quantile with 1 degree of freedom at 1 - 1e-3 is 9.5: a cost 6 lower), and a cost
// that does not rise 2 standard errors out: not valid, each named
TEST(IntervalCheckTest, EnvelopeWithALowerPointOrNoRiseIsNotValid) {
  const Envelope e;
  const double c0 = 0.5 * e.r.squaredNorm();
  RuggedEnvelope env = e.Check(
      [&](int v, double d) { return v == 1 && d > 1.5 * e.se[1] ? c0 - 6.0 : e.Model(v, d); });
  EXPECT_FALSE(env.valid);
  EXPECT_EQ(env.lower.rfind("b +2 std: cost -6", 0), 0u) << env.lower;
  // a lower cost within the noise is no lower point
  env = e.Check(
      [&](int v, double d) { return v == 1 && d > 1.5 * e.se[1] ? c0 - 4.0 : e.Model(v, d); });
  EXPECT_EQ(env.lower, "");
  EXPECT_FALSE(env.valid);  // but it does not rise there
  EXPECT_EQ(env.unbounded.rfind("b +2 std: cost -4", 0), 0u) << env.unbounded;
  // flat 1 standard error out, rising at 2: valid
  env = e.Check([&](int v, double d) { return std::abs(d) < 1.5 * e.se[v] ? c0 : e.Model(v, d); });
  EXPECT_TRUE(env.valid);
}

}  // namespace
}  // namespace mjsysid
