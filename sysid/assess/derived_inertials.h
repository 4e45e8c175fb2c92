// The physical quantities of the bodies fitted through body_inertial (core/inertia_cholesky.h):
// a user reads a body's mass, centre of mass and principal moments, not its log-Cholesky
// variables. Problem::Fit calls DeriveInertials after the uncertainty step.
#pragma once

#include <mujoco/mujoco.h>

#include <string>
#include <vector>

#include "sysid/types.h"

namespace mjsysid {

// One model and the physical parameters of a fit. For every body of `model` that has at least
// one body_inertial parameter applying to `model_name` (FitParameter::AppliesTo), returns 7
// DerivedQuantity in this order: "<prefix><body>.mass" (kg), ".com[0..2]" (m, body frame),
// ".inertia[0..2]" (kg m^2, principal moments ascending). The body's 10 variables are the
// estimates where fitted and the model's own values elsewhere; their covariance is the block of
// `covariance` (np x np over `params`, physical units, as FitResult::uncertainty.covariance's top
// left) with zero rows for the variables not fitted; the quantities' covariance is propagated by
// PhysicalInertialCovariance (delta method). `values`: the np estimates; `std_errors`: the np
// standard errors (a non-finite one makes the derived std_error +inf; `covariance` empty: NaN).
// prefix: "" or "<model>/" to keep names unique across models.
std::vector<DerivedQuantity> DeriveInertials(const mjModel& model, const std::string& model_name,
                                             const std::vector<FitParameter>& params,
                                             const Eigen::VectorXd& values,
                                             const Eigen::VectorXd& std_errors,
                                             const Eigen::MatrixXd& covariance,
                                             const std::string& prefix);

}  // namespace mjsysid
