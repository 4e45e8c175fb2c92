// The fit policy (Problem::Fit): one fit pass (sysid/fit/pass.h) and, for auto multiple
// shooting, a second one in segments after a Jacobian warning or a failure; their records
// combined (sysid/fit/policy.cc).
#pragma once

#include "sysid/solve/fit_state.h"
#include "sysid/types.h"

namespace mjsysid {

// Fits the problem whose state parts holds (borrowed for the call). Throws like Problem::Fit.
FitResult FitWithPolicy(const FitParts& parts, const FitOptions& options);

}  // namespace mjsysid
