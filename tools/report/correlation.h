// The report's parameter-correlation section: the correlation matrix of the estimates,
// r_ij = C_ij / sqrt(C_ii C_jj) from the result's covariance (FitResult::uncertainty.covariance,
// the parameters' order), as a table of coloured cells (blue -1, white 0, red +1) with the value in
// each cell and both names on hover, and the pairs with |r| >= kStrongCorrelation listed in words.
// A parameter without a variance (fixed, unidentifiable: a zero or non-finite diagonal) has no
// correlation: its cells are dashes.
#pragma once

#include <Eigen/Core>
#include <string>

#include "sysid/io/result.h"

namespace mjsysid::report {

// |r| at or above this is listed under the matrix: the data tell the pair's combination far better
// than either parameter (at 0.95 a joint interval's long axis is 6x its short one)
inline constexpr double kStrongCorrelation = 0.95;

// n x n correlations of an n x n covariance; NaN in the rows and columns of a variable without a
// positive finite variance (the diagonal 1 otherwise)
Eigen::MatrixXd CorrelationMatrix(const Eigen::MatrixXd& covariance);

// the section: "<h2>Parameter correlation</h2>", the table and the strong pairs; a note instead of
// the table when the result has fewer than two parameters or no covariance of their size
std::string CorrelationSection(const io::FitResultFile& result);

}  // namespace mjsysid::report
