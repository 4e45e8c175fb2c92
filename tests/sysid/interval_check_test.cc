// CheckIntervalScale (sysid/interval_check.h): the cost at the estimate +- one standard error
// against the Jacobian's quadratic model, on hand-made residuals r(p) = a (p - p0) + noise-like
// offsets, smooth and with a jump inside the interval.
#include "sysid/interval_check.h"

#include <gtest/gtest.h>

#include <cmath>

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

}  // namespace
}  // namespace mjsysid
