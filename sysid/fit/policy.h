// The fit policy (Problem::Fit): the subset start (sysid/fit/subset_start.h), then one fit pass
// (sysid/fit/pass.h) and, for auto multiple
// shooting, a second one in segments after a Jacobian warning or a failure; then the global stage
// (sysid/fit/global_stage.h); then, for a fit that converged in segments, its estimate simulated in
// one piece (model_mismatch where that smooth one-piece rollout does not explain the data); their
// records combined (sysid/fit/policy.cc).
#pragma once

#include "sysid/solve/fit_state.h"
#include "sysid/types.h"

namespace mjsysid {

// Fits the problem whose state parts holds (borrowed for the call). Throws like Problem::Fit.
FitResult FitWithPolicy(const FitParts& parts, const FitOptions& options);

}  // namespace mjsysid
