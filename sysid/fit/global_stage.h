// The global stage (FitOptions::global_stage, experiment `solver.global`): after the local fit
// (one pass, and auto's refit in segments: sysid/fit/policy.cc) ends other than converged, the fit
// goes on by itself from the local estimate, by horizon continuation, and keeps the better point.
//
// Why: on contact-rich and chaotic models a least-squares fit started 40 % off stops in another
// minimum (docs/stress.md, "Outside suite"): free segment states drift into another contact mode,
// an accelerometer's jumps make the cost rugged, single shooting's cost is rugged over a long
// horizon. Measured on that suite (docs/numerics.md, "Global stage"), what finds the truth from
// such starts is a short horizon whose states are held on the logged ones, with the jumping
// sensors left out (a nearly convex equation-error-like cost), followed by the local fit's own
// horizon from there.
//
// One round, from the best estimate so far:
//   1. continuation: segments of kContinuationSteps simulation steps, every segment state held on
//      the data (logged qpos/qvel or joint sensors), the jumping sensors (touch, accelerometer,
//      force, torque) left out: the parameters alone are solved;
//   2. the local fit's horizon (its segment length, and its contact-segment treatment) from the
//      continuation's end point, segment states held on the data first, then free.
// Round 2's final cost is a cost of the same function as the local fit's (the same horizon,
// sensors and weights), so the two are compared directly: round 2 replaces the best when its cost
// is lower by more than the noise explains (sysid/assess/chi_square.h, AboveByMoreThanNoise), and
// then another round starts from it; else the stage ends. At most kMaxGlobalRounds rounds; no
// pass starts once the stage has simulated global_budget x the local fit's simulation steps (steps,
// not seconds: the same rounds at any load), and an interrupt stops it. A pass that starts inside
// the budget runs to its end (measured overruns up to 1.7x, docs/stress.md).
//
// Runs when: options.global_stage, the local fit ended not_converged, model_mismatch,
// jacobian_unreliable or did_not_move (never after converged or interrupted), the
// fit is not sharded (sysid/mpi/), and the segment states can come from the data (else it says so
// and ends). Measurement terms and control delays restart at their own initial values in each pass.
//
// The result: the better of the local fit and the stage's best, with the user's starts as
// `initial`, the local fit's initial cost and initial signals, every pass's time, steps, ledger
// rows (prefixed "global stage round N ...") and trace, and one warning saying what the stage did:
// how much lower it ended, or that it found nothing lower (the local result stands). The status is
// the kept pass's own (sysid/assess/fit_status.h).
#pragma once

#include "sysid/solve/fit_state.h"
#include "sysid/types.h"

namespace mjsysid {

// the continuation's segments, in simulation steps
constexpr int kContinuationSteps = 5;
// rounds at most
constexpr int kMaxGlobalRounds = 3;

// the horizon of the local fit's result
struct LocalMode {
  int segment_steps = 0;          // 0: single shooting
  bool contact_segments = false;  // auto's contact segments
};

// local: the local fit's result (its horizon: mode). Returns it, or the stage's better point. A
// pass of the stage that throws (a simulation error) or is interrupted ends the stage: the best
// point so far stands and the warning says why; only std::bad_alloc propagates. The problem's
// parameters keep the user's starts however the stage ends.
FitResult GlobalStage(const FitParts& parts, const FitOptions& options, const LocalMode& mode,
                      FitResult local);

}  // namespace mjsysid
