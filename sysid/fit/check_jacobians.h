// Problem::CheckJacobians: every residual block's analytic Jacobian at the initial point against
// Ceres' central differences (sysid/fit/check_jacobians.cc).
#pragma once

#include "sysid/problem.h"  // JacobianCheck
#include "sysid/solve/fit_state.h"

namespace mjsysid {

// The check of the problem whose state parts holds (borrowed for the call): prepares the fit
// (the equation-error starts first) and checks each block. Throws like Problem::Fit.
JacobianCheck CheckJacobiansAt(const FitParts& parts, const FitOptions& options);

}  // namespace mjsysid
