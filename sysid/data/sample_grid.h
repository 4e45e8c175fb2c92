// The simulation grid of one logged sequence: a log's samples come at their own times (any rate,
// jitter, gaps), the simulation runs on the model's timestep. Built by PrepareFit from
// FitSequence; read by the evaluation cache (the controls of each step) and the cost function
// (where each measured sample is read). Eigen only.
//
// Grid. Step n is at t_0 + n dt, n = 0 .. steps - 1, t_0 the first measured sample's time and dt
// the model's timestep (seconds). Measured sample k at time t_k sits at position[k] = (t_k - t_0)
// / dt steps and is compared with the simulated sensors interpolated between the two steps around
// it (DelayedSample, sysid/solve/residual_model.h; the sensor delay is subtracted from the same
// position). A position within kOnGridTolerance steps of a whole number is that number: a log on
// the grid reads the steps themselves, exactly as before off-grid logs were accepted.
//
// Controls. Each actuator's logged controls (at their own times) reach step n by a hold rule:
// zero-order hold (what a digital controller does: each command holds until the next) or linear
// interpolation between the two around t_n; before the first logged control the first is held
// (ControlBefore::kHold, the default) or the actuator gets 0 (kZero), after the last the last. An
// optional transport delay d (seconds, per actuator) shifts the controls before the hold. With
// zero-order hold step n sees the step average of the held, delayed command u_zoh:
//   u_n = (1/dt) * integral over [t_n, t_n + dt] of u_zoh(t - d) dt,
// the command in force at the step's start weighted by the fraction of the step until the next
// command, and so on: piecewise linear in d (and in the command times), where a point sample
// would jump. Commands on the grid with d a whole number of steps give exactly the command in
// force at t_n - d (a command within kOnGridTolerance of a step's end belongs to the next step).
// Linear interpolation samples at t_n - d.
//
// Segments (multiple shooting) are in simulation steps. A segment [k0, k0 + T) owns the samples
// whose position lies in it; when one lies past its last step and the sequence goes on, it
// simulates one step more (SimulatedSteps), so that the interpolation reads its own rollout, never
// the next segment's.
//
// Failure: BuildSampleGrid throws std::invalid_argument for times that are not finite and strictly
// increasing or a timestep that is not positive (the loaders check logs before,
// sysid/io/time_base.h).
#pragma once

#include <Eigen/Core>
#include <string>
#include <vector>

#include "core/state.h"
#include "sysid/types.h"  // ControlHold

namespace mjsysid {

struct SampleGrid {
  // in steps: 2 us at a 2 ms timestep. Covers rounded decimal times and float32 time (its
  // rounding, 6e-8 t, stays below it for logs up to ~30 s at 2 ms); far below any real jitter.
  static constexpr double kOnGridTolerance = 1e-3;
  int steps = 0;                 // N simulated steps
  RowMatrix ctrl;                // N x nu: the control of each step
  std::vector<double> position;  // T: position of each measured sample, in steps, ascending
  bool on_grid = true;           // every position a whole number
  // the logged controls' positions in steps (Tc, before any delay) and the per-actuator delays
  // (nu, seconds) `ctrl` was held with: HoldControls holds them again at other delays (a fitted
  // control delay), and the evaluation cache keys its rollouts by `delay`
  std::vector<double> ctrl_position;
  std::vector<double> delay;
  ControlBefore before = ControlBefore::kHold;  // what HoldControls gives before the first control

  // the measured samples [*first, *first + *count) read by the segment of steps [k0, k0 + T)
  void SamplesOf(int k0, int T, int* first, int* count) const;
  // the steps simulated for that segment: T, plus one when one of its samples lies after its
  // last step and the sequence goes on
  int SimulatedSteps(int k0, int T) const;
};

// The grid of a sequence with measured sample times `time` (T, seconds, strictly increasing; empty:
// T samples on the grid, one per step, from x0_time), controls `ctrl` (Tc x nu) logged at
// `ctrl_time` (Tc, seconds, strictly increasing; empty: at the measured sample times, Tc = T), for
// a model with timestep dt. hold and delay: per actuator (empty: zero-order hold, no delay; else nu
// entries; delays in seconds, >= 0). `where` prefixes error messages. before: what every actuator
// gets before its first logged control (kept in the grid for HoldControls).
SampleGrid BuildSampleGrid(const Eigen::VectorXd& time, int T, double x0_time,
                           const RowMatrix& ctrl, const Eigen::VectorXd& ctrl_time,
                           const std::vector<ControlHold>& hold, const std::vector<double>& delay,
                           double dt, const std::string& where,
                           ControlBefore before = ControlBefore::kHold);

// The controls of steps [first, first + count) of grid g (count < 0: through the last step;
// count x nu into *out, resized, row 0 = step first) held from the logged controls `ctrl` (Tc x
// nu, at g.ctrl_position) by the rule above with per-actuator hold and delay (seconds; empty:
// zero-order hold, no delay) and g.before. Piecewise linear in each delay (zero-order hold); a
// negative delay shifts the controls earlier (used by a fitted delay's finite differences at its
// lower bound). Allocates only when *out changes shape (and a scratch list of the valid controls).
void HoldControls(const SampleGrid& g, const RowMatrix& ctrl, const std::vector<ControlHold>& hold,
                  const std::vector<double>& delay, double dt, RowMatrix* out, int first = 0,
                  int count = -1);

// The number of leading steps of grid g whose controls, held with per-actuator delay (seconds;
// empty: none), read before an actuator's first logged (not NaN) control in `ctrl` (Tc x nu, at
// g.ctrl_position): commands nobody logged (g.before says what they are). The largest over the
// actuators, at most g.steps; *actuator (when given) is the one, -1 when none.
int StepsBeforeFirstControl(const SampleGrid& g, const RowMatrix& ctrl,
                            const std::vector<double>& delay, double dt, int* actuator = nullptr);

}  // namespace mjsysid
