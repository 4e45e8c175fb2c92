// Stage 1 of a fit pass (sysid/fit/pass.h): the equation-error starts and PrepareFit, which
// validates the inputs and builds the prepared fit (sysid/solve/fit_state.h) in seven stages
// (sysid/fit/prepare.cc). A sharded fit's workers prepare a Problem without fitting it through
// sysid/fit/segment_evaluator.h.
#pragma once

#include <string>
#include <utility>
#include <vector>

#include "core/simulator.h"
#include "sysid/problem.h"
#include "sysid/solve/fit_state.h"
#include "sysid/types.h"

namespace mjsysid {

// What PrepareFit decided besides the prepared state: the rollouts at the initial values, the
// variables' names, bounds and starts, the Jacobian mode and the segments chosen
struct FitPlan {
  std::vector<Trajectory> initial;  // rollouts at the initial values
  std::vector<std::string> names;   // parameters, measurement terms, then control delays
  std::vector<std::pair<double, double>> mbounds;  // bounds of the m block (terms, delays)
  std::vector<double> minitial;                    // their initial values
  std::string jacobian_mode;
  int segment_steps = 0;    // multiple shooting as chosen (0: single shooting)
  SegmentRecord segments;   // why (FitResult::segment_reason)
  double probe_rate = 0;    // growth rate per step of the auto probe
  double probe_growth = 0;  // its largest growth beyond linear (HorizonChoice::growth)
  FitResult::EventWindows event_windows;  // auto's contact segments (sysid/data/event_windows.h)
  bool contact_segments = false;          // auto chose contact segments (HorizonChoice)
};

// Validates the inputs (names, shapes, bounds, the data every parameter must move) and builds what
// a fit runs on (sysid/fit/prepare.cc): the simulators with their parameters, the variables,
// the sample grids, the segments, the initial rollouts and Jacobians and the evaluation cache.
// Throws std::invalid_argument / ParameterError on bad input.
FitPlan PrepareFit(const FitParts& parts, const FitOptions& options);

// throws ParameterError naming the first parameter g with !moves[g] (its Jacobian column is zero
// in every sequence at the initial values): what Prepare checks, or the caller of a sharded start
// with moves combined over every shard
void CheckParametersMove(const PreparedFit& fit, const std::vector<bool>& moves);

// A sharded start (ShardStart) simulated only the owned sequences at the initial values:
// rolls out the others (those with an empty trajectory in initial; no Jacobians), and leaves the
// simulators at the initial parameters
void RolloutUnowned(PreparedFit* fit, std::vector<Trajectory>* initial);

// initial: auto (FitParameter::initial_auto): the equation-error start of each model's `auto`
// parameters from its sequences' logged qpos and qvel (sysid/data/equation_error.h); a parameter
// that cannot be solved starts at its model's value. The marks are cleared, so that a refit (auto
// multiple shooting) starts from the same values. Returns one line per model, for the warnings.
// threads: the fit's (FitOptions::threads), for the samples' inverse dynamics.
std::vector<std::string> SolveAutoStarts(PreparedFit* fit, int threads);

// the fitted control delay each actuator of m follows: the index into `delays` of its own (actuator
// named), else of the shared one (actuator ""); -1 for an actuator that follows none. nu entries.
std::vector<int> ControlDelayOfActuators(const std::vector<FitControlDelay>& delays,
                                         const mjModel& m);

// A held-out sequence (never fitted: sysid/run/validation.h) checked against its model as
// PrepareFit checks a fitted one: its matrices' shapes, its initial and logged states, its
// controls (no infinite value, no NaN before the first valid one) and its times on the model's
// steps (sysid/data/sample_grid.h). Throws std::invalid_argument starting with `where`.
void CheckHeldOutSequence(const FitSequence& sequence, const mjModel& m, const std::string& where);

// The parts of problem's fit state (borrowed: valid while problem lives)
FitParts PartsOf(Problem* problem);

}  // namespace mjsysid
