// The simulation grid of a logged sequence (sysid/data/sample_grid.h) on hand-made times and
// controls: positions (whole numbers on the grid, fractions off it), the steps simulated, the
// samples of a segment, zero-order hold and linear interpolation of controls at their own times, a
// transport delay, NaN controls held from the last valid value, the commands before the first
// logged one (held or zero) and how many steps read them.
#include "sysid/data/sample_grid.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <vector>

namespace mjsysid {
namespace {

constexpr double kDt = 0.002;
const double kNan = std::numeric_limits<double>::quiet_NaN();

Eigen::VectorXd Times(std::vector<double> t) {
  return Eigen::Map<Eigen::VectorXd>(t.data(), static_cast<Eigen::Index>(t.size()));
}

RowMatrix Column(std::vector<double> u) {
  RowMatrix m(static_cast<Eigen::Index>(u.size()), 1);
  for (size_t i = 0; i < u.size(); ++i) m(static_cast<Eigen::Index>(i), 0) = u[i];
  return m;
}

TEST(SampleGridTest, OnGridTimesAreWholeSteps) {
  // k * dt from 1.5 s, rounded as a logger writes them; and no times at all
  std::vector<double> t;
  for (int k = 0; k < 50; ++k) t.push_back(1.5 + k * kDt);
  const RowMatrix u = Column(std::vector<double>(50, 0.0));
  for (const Eigen::VectorXd& time : {Times(t), Eigen::VectorXd()}) {
    const SampleGrid g = BuildSampleGrid(time, 50, 1.5, u, {}, {}, {}, kDt, "");
    EXPECT_TRUE(g.on_grid);
    EXPECT_EQ(g.steps, 50);
    for (int k = 0; k < 50; ++k) EXPECT_EQ(g.position[k], k);
    EXPECT_EQ(g.SimulatedSteps(0, 25), 25);
  }
}

TEST(SampleGridTest, OffGridPositionsAndSteps) {
  // 100 Hz with jitter against a 2 ms model: positions 0, 5.15, 9.9, 15.0 (snapped), 20.4
  const Eigen::VectorXd t = Times({0.0, 0.0103, 0.0198, 0.030000000001, 0.0408});
  const RowMatrix u = Column({1, 2, 3, 4, 5});
  const SampleGrid g = BuildSampleGrid(t, 5, 0.0, u, {}, {}, {}, kDt, "");
  EXPECT_FALSE(g.on_grid);
  EXPECT_NEAR(g.position[1], 5.15, 1e-9);
  EXPECT_NEAR(g.position[2], 9.9, 1e-9);
  EXPECT_EQ(g.position[3], 15.0);
  EXPECT_EQ(g.steps, 22);  // the last sample (20.4) lies between steps 20 and 21
  // zero-order hold: the average over each step of the held control
  EXPECT_EQ(g.ctrl(0, 0), 1);
  EXPECT_NEAR(g.ctrl(5, 0), 0.15 * 1 + 0.85 * 2, 1e-9);  // 2 from 5.15 on
  EXPECT_EQ(g.ctrl(6, 0), 2);
  EXPECT_NEAR(g.ctrl(9, 0), 0.9 * 2 + 0.1 * 3, 1e-9);
  EXPECT_EQ(g.ctrl(15, 0), 4);  // on the sample
  EXPECT_EQ(g.ctrl(21, 0), 5);
  // segments of 10 steps: [0, 10) holds samples 0..2, and the one at 9.9 lies past step 9
  int first = -1, count = -1;
  g.SamplesOf(0, 10, &first, &count);
  EXPECT_EQ(first, 0);
  EXPECT_EQ(count, 3);
  EXPECT_EQ(g.SimulatedSteps(0, 10), 11);
  g.SamplesOf(10, 10, &first, &count);
  EXPECT_EQ(first, 3);
  EXPECT_EQ(count, 1);
  EXPECT_EQ(g.SimulatedSteps(10, 10), 10);  // 15.0 lies inside
  EXPECT_EQ(g.SimulatedSteps(20, 2), 2);    // the last segment: nothing after it
}

TEST(SampleGridTest, ControlsAtTheirOwnTimesHeldOrInterpolatedAndDelayed) {
  // sensors every 1 ms for 20 ms; controls at 0, 5, 10, 15 ms (200 Hz), values 0, 10, 20, 30
  std::vector<double> ts;
  for (int k = 0; k <= 20; ++k) ts.push_back(k * 0.001);
  const Eigen::VectorXd t = Times(ts), tc = Times({0.0, 0.005, 0.010, 0.015});
  const RowMatrix u(Column({0, 10, 20, 30}));
  RowMatrix u2(4, 2);
  u2 << u, u;
  const SampleGrid g = BuildSampleGrid(
      t, 21, 0.0, u2, tc, {ControlHold::kZeroOrder, ControlHold::kLinear}, {0.0, 0.0}, kDt, "");
  ASSERT_EQ(g.steps, 11);
  // step 3 (6 ms): held 10; linear 10 + 0.2 * 10
  EXPECT_EQ(g.ctrl(3, 0), 10);
  EXPECT_NEAR(g.ctrl(3, 1), 12, 1e-12);
  // past the last control: held
  EXPECT_EQ(g.ctrl(10, 0), 30);
  EXPECT_EQ(g.ctrl(10, 1), 30);
  // a 3 ms transport delay: step 4 (8 ms) sees the control of 5 ms (zoh: 10; linear: 10)
  const SampleGrid d = BuildSampleGrid(t, 21, 0.0, u2, tc, {}, {0.003, 0.003}, kDt, "");
  EXPECT_EQ(d.ctrl(3, 0), 0);  // 6 - 3 = 3 ms: still the first control
  EXPECT_EQ(d.ctrl(4, 0), 10);
}

// Zero-order hold gives each step the average of the held (and delayed) command over the step:
// commands on the grid with a delay of whole steps give exactly the command in force at each
// step's start (the rule before the average), and the average is linear in the delay between two
// commands.
TEST(SampleGridTest, HeldCommandsAreAveragedOverEachStep) {
  // commands every 5 steps (100 Hz against 2 ms), values 3, -1, 7, 2 at rows of 10 ms
  const Eigen::VectorXd t = Times({0.0, 0.01, 0.02, 0.03});
  const Eigen::VectorXd tc = Times({0.0, 0.01, 0.02, 0.03});
  const RowMatrix u = Column({3, -1, 7, 2});
  for (const double delay : {0.0, 0.004, 0.01}) {
    const SampleGrid g = BuildSampleGrid(t, 4, 0.0, u, tc, {}, {delay}, kDt, "");
    ASSERT_EQ(g.steps, 16);
    const int shift = static_cast<int>(std::lround(delay / kDt));
    for (int n = 0; n < g.steps; ++n) {
      // the command in force at step n's start: the last one logged at or before n - shift
      const int j = std::min(3, std::max(0, (n - shift) / 5));
      EXPECT_EQ(g.ctrl(n, 0), u(n - shift < 0 ? 0 : j, 0)) << "delay " << delay << " step " << n;
    }
  }
  // between whole steps the average moves linearly: step 5 with a delay of s steps covers the
  // command 3 for s of the step and -1 for the rest
  for (const double s : {0.25, 0.5, 0.75}) {
    const SampleGrid g = BuildSampleGrid(t, 4, 0.0, u, tc, {}, {s * kDt}, kDt, "");
    EXPECT_NEAR(g.ctrl(5, 0), 3 * s + -1 * (1 - s), 1e-9) << s;
    EXPECT_NEAR(g.ctrl(4, 0), 3, 1e-12) << s;
  }
}

TEST(SampleGridTest, NanControlsAreHeldFromTheLastValidOne) {
  const RowMatrix u = Column({1, kNan, kNan, 4});
  const SampleGrid g = BuildSampleGrid({}, 4, 0.0, u, {}, {ControlHold::kLinear}, {}, kDt, "");
  EXPECT_EQ(g.ctrl(0, 0), 1);
  // linear between the valid neighbours 1 (step 0) and 4 (step 3)
  EXPECT_NEAR(g.ctrl(1, 0), 2, 1e-12);
  const SampleGrid z = BuildSampleGrid({}, 4, 0.0, u, {}, {}, {}, kDt, "");
  EXPECT_EQ(z.ctrl(2, 0), 1);
  EXPECT_EQ(z.ctrl(3, 0), 4);
}

// Before the first logged command: with a delay of 3 steps, the first 3 steps read before it; they
// get the first command (before: hold, the default) or 0 (before: zero), the later steps the same
// either way; under both holds. A partial step (delay 2.5 steps) averages 0 with the first.
TEST(SampleGridTest, BeforeTheFirstCommandHoldsItOrGivesZero) {
  const Eigen::VectorXd t = Times({0.0, 0.01, 0.02, 0.03});
  const RowMatrix u = Column({3, -1, 7, 2});
  for (const ControlHold h : {ControlHold::kZeroOrder, ControlHold::kLinear}) {
    SCOPED_TRACE(ControlHoldName(h));
    const SampleGrid hold = BuildSampleGrid(t, 4, 0.0, u, t, {h}, {3 * kDt}, kDt, "");
    const SampleGrid zero =
        BuildSampleGrid(t, 4, 0.0, u, t, {h}, {3 * kDt}, kDt, "", ControlBefore::kZero);
    EXPECT_EQ(hold.before, ControlBefore::kHold);
    EXPECT_EQ(zero.before, ControlBefore::kZero);
    for (int n = 0; n < 3; ++n) {
      EXPECT_EQ(hold.ctrl(n, 0), 3) << n;
      EXPECT_EQ(zero.ctrl(n, 0), 0) << n;
    }
    for (int n = 3; n < hold.steps; ++n) EXPECT_EQ(zero.ctrl(n, 0), hold.ctrl(n, 0)) << n;
    EXPECT_EQ(StepsBeforeFirstControl(hold, u, {3 * kDt}, kDt), 3);
    // HoldControls at another delay keeps the grid's rule
    RowMatrix again;
    HoldControls(zero, u, {h}, {kDt}, kDt, &again);
    EXPECT_EQ(again(0, 0), 0);
    EXPECT_EQ(again(1, 0), 3);
  }
  const SampleGrid half =
      BuildSampleGrid(t, 4, 0.0, u, t, {}, {2.5 * kDt}, kDt, "", ControlBefore::kZero);
  EXPECT_EQ(half.ctrl(1, 0), 0);
  EXPECT_NEAR(half.ctrl(2, 0), 0.5 * 3, 1e-12);
  EXPECT_EQ(StepsBeforeFirstControl(half, u, {2.5 * kDt}, kDt), 3);
}

// the steps that read before the first logged command: none without a delay when the commands
// start with the samples, none when they start early enough (4 steps before, delay 3 steps), the
// rest when they start too late (2 steps before: 1 step; 2 steps after, no delay: 2 steps); the
// actuator that reaches furthest is named, NaN rows before an actuator's first value count
TEST(SampleGridTest, CountsTheStepsThatReadBeforeTheFirstCommand) {
  const Eigen::VectorXd t = Times({0.0, 0.01, 0.02, 0.03});
  const RowMatrix u = Column({3, -1, 7, 2});
  const SampleGrid g = BuildSampleGrid(t, 4, 0.0, u, t, {}, {}, kDt, "");
  EXPECT_EQ(StepsBeforeFirstControl(g, u, {}, kDt), 0);
  EXPECT_EQ(StepsBeforeFirstControl(g, u, {0.0}, kDt), 0);
  const Eigen::VectorXd early = Times({-4 * kDt, 0.01, 0.02, 0.03});
  EXPECT_EQ(StepsBeforeFirstControl(BuildSampleGrid(t, 4, 0.0, u, early, {}, {}, kDt, ""), u,
                                    {3 * kDt}, kDt),
            0);
  const Eigen::VectorXd less = Times({-2 * kDt, 0.01, 0.02, 0.03});
  EXPECT_EQ(StepsBeforeFirstControl(BuildSampleGrid(t, 4, 0.0, u, less, {}, {}, kDt, ""), u,
                                    {3 * kDt}, kDt),
            1);
  const Eigen::VectorXd late = Times({2 * kDt, 0.01, 0.02, 0.03});
  EXPECT_EQ(
      StepsBeforeFirstControl(BuildSampleGrid(t, 4, 0.0, u, late, {}, {}, kDt, ""), u, {}, kDt), 2);
  RowMatrix two(4, 2);
  two << 1, kNan, 2, kNan, 3, 5, 4, 6;  // actuator 1 logs from the third row (20 ms)
  int actuator = -1;
  EXPECT_EQ(StepsBeforeFirstControl(BuildSampleGrid(t, 4, 0.0, two, t, {}, {}, kDt, ""), two, {},
                                    kDt, &actuator),
            10);
  EXPECT_EQ(actuator, 1);
}

TEST(SampleGridTest, BadTimesAreErrors) {
  const RowMatrix u = Column({0, 0, 0});
  EXPECT_THROW(BuildSampleGrid(Times({0, 0.01, 0.01}), 3, 0, u, {}, {}, {}, kDt, ""),
               std::invalid_argument);
  EXPECT_THROW(BuildSampleGrid(Times({0, kNan, 0.02}), 3, 0, u, {}, {}, {}, kDt, ""),
               std::invalid_argument);
  EXPECT_THROW(BuildSampleGrid(Times({0, 0.01, 0.02}), 3, 0, u, {}, {}, {}, 0.0, ""),
               std::invalid_argument);
}

}  // namespace
}  // namespace mjsysid
