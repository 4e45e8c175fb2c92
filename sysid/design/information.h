// The information a rollout carries about the parameters: the Fisher information matrix of the
// fitted sensors, and the predicted standard errors and design criteria that follow from it.
//
// Contract:
// - F = sum_k J_k^T W J_k + P, J_k the rows of the sensors' Jacobian dy_k/dp (Sensitivity::DyDp,
//   rows k * ns + c) of the weighted columns c, W = diag(1 / sigma_c^2), P = diag(1 / prior
//   sigma^2) for parameters with a Gaussian prior (else 0). Units: the parameters' own.
// - The predicted covariance is F^-1 (the fit's s^2 (J^T J)^-1 with correct sigmas, to first
//   order). Relative standard errors divide by |value| (a parameter at 0 keeps its absolute one).
// - Criteria (lower is better, CriterionValue), on the relative information R = D F D,
//   D = diag(|value|) (1 where a value is 0), so that they do not depend on units:
//     kDOptimal          -log det R (D-optimal: the smallest joint confidence ellipsoid)
//     kWorstRelativeStd  the largest relative standard error
//     kConditionNumber   lambda_max(R) / lambda_min(R)
//   A singular R (a parameter the rollout does not move) gives +inf and infinite standard errors.
#pragma once

#include <Eigen/Core>
#include <string>
#include <vector>

#include "core/simulator.h"

namespace mjsysid::design {

enum class DesignCriterion { kDOptimal, kWorstRelativeStd, kConditionNumber };
// "d_optimal", "worst_relative_std", "condition_number"
const char* CriterionName(DesignCriterion c);
// the criterion of a name; false when it names none
bool ParseCriterion(const std::string& name, DesignCriterion* out);

// the sensordata columns fitted and their noise
struct SensorWeights {
  std::vector<int> columns;   // sensordata columns
  std::vector<double> sigma;  // > 0, one per column
};

struct Information {
  Eigen::MatrixXd fisher;        // np x np, F (parameters' units)
  Eigen::VectorXd std;           // sqrt(diag(F^-1)); +inf where F is singular
  Eigen::VectorXd relative_std;  // std / |value| (std where value is 0)
  double log_det = 0;            // log det R; -inf when singular
  double worst_relative_std = 0;
  double condition = 0;  // lambda_max(R) / lambda_min(R); +inf when singular
};

// the information of the Jacobians of one or more rollouts (ns = the model's nsensordata) at the
// parameter values `values`; prior_precision: 1 / sigma^2 per parameter (0: no prior)
Information InformationOf(const std::vector<Sensitivity>& jacobians, int ns,
                          const SensorWeights& sensors, const Eigen::VectorXd& values,
                          const Eigen::VectorXd& prior_precision);

// the criterion's value (lower is better)
double CriterionValue(const Information& info, DesignCriterion criterion);

// What the search minimises: the criterion, except that the largest relative standard error
// (a maximum, flat wherever another parameter is not the worst) is replaced by the 8-norm of
// the relative standard errors, a smooth bound within a factor np^(1/8) of it that still
// rewards improving the parameters that are close to the worst.
double SearchScore(const Information& info, DesignCriterion criterion);

}  // namespace mjsysid::design
